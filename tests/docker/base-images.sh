#!/usr/bin/env bash
# Builds, from Debian's packages alone, the three base images that the Dockerfile and
# examples/compose.yaml take as build arguments, for a Docker engine that reaches no image
# registry (docs/farm.md, "Docker without a registry"):
#
#   photonbox/debian:bookworm      a debootstrap minbase root: stands in for debian:bookworm-slim
#   photonbox/rust:bookworm        that root, gcc, and this machine's Rust toolchain (its sysroot,
#                                  `rustc --print sysroot`): stands in for rust:1.95-slim-bookworm
#   photonbox/postgres:15          that root and Debian's PostgreSQL 15, started by
#                                  tests/docker/postgres-entrypoint.sh, which takes the official
#                                  image's POSTGRES_USER/POSTGRES_PASSWORD/POSTGRES_DB: stands in
#                                  for postgres:15
#
# An image the engine already has is kept (delete it to rebuild). Needs root (debootstrap)
# and Debian's mirror. Extra CA certificates this machine trusts (a proxy's, in
# /usr/local/share/ca-certificates) go into the Rust image, so that cargo reaches crates.io
# from inside a build the way it does from here.
set -euo pipefail
cd "$(dirname "$0")"
here="$(pwd)"
mirror="${DEBIAN_MIRROR:-http://deb.debian.org/debian}"
work="$(mktemp -d "${TMPDIR:-/tmp}/photonbox-images.XXXXXX")"
trap 'rm -rf "$work"' EXIT
sudo=""
if [ "$(id -u)" != 0 ]; then sudo="sudo"; fi

have() { docker image inspect "$1" >/dev/null 2>&1; }
say() { echo "tests/docker/base-images.sh: $*" >&2; }

if ! have photonbox/debian:bookworm; then
  say "debootstrap bookworm (minbase) into $work/root"
  command -v debootstrap >/dev/null ||
    $sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -q debootstrap >&2
  $sudo debootstrap --variant=minbase bookworm "$work/root" "$mirror" >"$work/debootstrap.log" ||
    { tail -20 "$work/debootstrap.log" >&2; exit 1; }
  $sudo sh -c "echo 'deb $mirror bookworm main' > '$work/root/etc/apt/sources.list'"
  $sudo rm -rf "$work/root/var/lib/apt/lists/"* "$work/root/var/cache/apt/"*.bin
  $sudo tar -C "$work/root" -c . |
    docker import -c 'ENV LANG=C.UTF-8' -c 'CMD ["/bin/bash"]' - photonbox/debian:bookworm >&2
  $sudo rm -rf "$work/root"
fi

if ! have photonbox/rust:bookworm; then
  sysroot="$(rustc --print sysroot)"
  say "photonbox/rust:bookworm from $sysroot ($(rustc --version))"
  mkdir -p "$work/rust/toolchain" "$work/rust/ca"
  cp -a "$sysroot/bin" "$sysroot/lib" "$sysroot/libexec" "$work/rust/toolchain/"
  if compgen -G "/usr/local/share/ca-certificates/*.crt" >/dev/null; then
    cp /usr/local/share/ca-certificates/*.crt "$work/rust/ca/"
  fi
  cat >"$work/rust/Dockerfile" <<'EOF'
FROM photonbox/debian:bookworm
RUN apt-get update && apt-get install -y --no-install-recommends gcc libc6-dev ca-certificates \
    && rm -rf /var/lib/apt/lists/*
COPY ca/ /usr/local/share/ca-certificates/
RUN update-ca-certificates
COPY toolchain/ /usr/local/rust/
ENV PATH=/usr/local/cargo/bin:/usr/local/rust/bin:$PATH CARGO_HOME=/usr/local/cargo
RUN cargo --version && rustc --version
EOF
  docker build -q -t photonbox/rust:bookworm "$work/rust" >&2
fi

if ! have photonbox/postgres:15; then
  say "photonbox/postgres:15 from Debian's postgresql-15"
  mkdir -p "$work/pg"
  cp "$here/postgres-entrypoint.sh" "$work/pg/"
  cat >"$work/pg/Dockerfile" <<'EOF'
FROM photonbox/debian:bookworm
RUN mkdir -p /etc/postgresql-common \
    && echo 'create_main_cluster = false' > /etc/postgresql-common/createcluster.conf \
    && apt-get update \
    && apt-get install -y --no-install-recommends postgresql-15 postgresql-client-15 \
    && rm -rf /var/lib/apt/lists/* \
    && mkdir -p /var/lib/postgresql/data && chown -R postgres:postgres /var/lib/postgresql
COPY postgres-entrypoint.sh /usr/local/bin/
ENV PATH=/usr/lib/postgresql/15/bin:$PATH PGDATA=/var/lib/postgresql/data
USER postgres
VOLUME ["/var/lib/postgresql/data"]
EXPOSE 5432
ENTRYPOINT ["postgres-entrypoint.sh"]
EOF
  docker build -q -t photonbox/postgres:15 "$work/pg" >&2
fi
