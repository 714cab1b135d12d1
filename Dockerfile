# photonbox render server: multi-stage build, slim runtime, non-root, data volume.
#
#   docker build -t photonbox .
#   docker run -p 8080:8080 -v photonbox-data:/data photonbox
#
# The admin sign-in URL is printed in the container's log (docker logs). The same image is a
# farm's API or worker: `docker run photonbox serve --store postgres://...` or
# `docker run photonbox worker --store postgres://...` (examples/compose.yaml).
#
# Without a reachable image registry, build the base images from Debian's packages first and
# name them (docs/farm.md, "Docker without a registry"):
#   tests/docker/base-images.sh
#   docker build -t photonbox --build-arg BUILD_IMAGE=photonbox/rust:bookworm \
#       --build-arg RUNTIME_IMAGE=photonbox/debian:bookworm .
# PROFILE picks the cargo profile (default release, fat LTO; the container tests use `quick`).

ARG BUILD_IMAGE=rust:1.95-slim-bookworm
ARG RUNTIME_IMAGE=debian:bookworm-slim

FROM ${BUILD_IMAGE} AS build
ARG PROFILE=release
WORKDIR /src
# gcc for rusqlite's bundled SQLite.
RUN apt-get update && apt-get install -y --no-install-recommends gcc libc6-dev \
    && rm -rf /var/lib/apt/lists/*
COPY Cargo.toml Cargo.lock ./
COPY .cargo .cargo
COPY src src
COPY benches benches
COPY examples examples
COPY web web
COPY scenes scenes
RUN cargo build --profile "$PROFILE" --locked --bin photonbox \
    && cp "target/$PROFILE/photonbox" /photonbox \
    && strip /photonbox

FROM ${RUNTIME_IMAGE}
RUN apt-get update && apt-get install -y --no-install-recommends curl ca-certificates \
    && rm -rf /var/lib/apt/lists/* \
    && useradd --system --uid 10001 --home-dir /data photonbox \
    && mkdir -p /data && chown photonbox /data
COPY --from=build /photonbox /usr/local/bin/photonbox
COPY --from=build /src/scenes /opt/photonbox/scenes
USER photonbox
# The built-in scenes are found as ./scenes by every role.
WORKDIR /opt/photonbox
VOLUME ["/data"]
EXPOSE 8080
# Both roles answer /healthz on 8080: `serve` once its store is open, `worker` (with its
# --addr) once it has joined the farm.
HEALTHCHECK --interval=10s --timeout=3s --start-period=10s --retries=3 \
    CMD curl -fsS http://127.0.0.1:8080/healthz || exit 1
ENTRYPOINT ["photonbox"]
CMD ["serve", "--addr", "0.0.0.0:8080", "--data", "/data"]
