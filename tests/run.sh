#!/usr/bin/env bash
# The project's one test command (README.md, "Set up on a fresh machine"; `.ci/run` runs it):
# installs what the tests need when it is missing, then runs every test.
#
# The browser tests (tests/browser/) drive Debian's headless Chromium through chromedriver and
# Debian's Firefox ESR through geckodriver. Debian has no geckodriver package (bookworm): it
# comes from crates.io then, into ~/.cargo/bin (a few minutes' build, once per machine).
# The farm's tests (tests/farm/) start Debian's PostgreSQL server in a temporary directory.
# The container tests (tests/container.rs) build the Dockerfile's image and bring up
# examples/compose.yaml on the Docker engine, from base images made by tests/docker/.
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH="${CARGO_HOME:-$HOME/.cargo}/bin:$PATH"
sudo=""
if [ "$(id -u)" != 0 ]; then sudo="sudo"; fi
apt_get() { $sudo env DEBIAN_FRONTEND=noninteractive apt-get "$@"; }
packages=()
command -v chromium >/dev/null || packages+=(chromium)
command -v chromedriver >/dev/null || packages+=(chromium-driver)
command -v firefox-esr >/dev/null || command -v firefox >/dev/null || packages+=(firefox-esr)
compgen -G "/usr/lib/postgresql/*/bin/postgres" >/dev/null || packages+=(postgresql)
command -v docker >/dev/null || packages+=(docker.io)
command -v docker-compose >/dev/null || docker compose version >/dev/null 2>&1 ||
  packages+=(docker-compose)
command -v debootstrap >/dev/null || packages+=(debootstrap)
if [ ${#packages[@]} -gt 0 ] || ! command -v geckodriver >/dev/null; then
  echo "tests/run.sh: installing what the tests need: ${packages[*]:-} geckodriver" >&2
  apt_get update -q
  if ! command -v geckodriver >/dev/null && [ -n "$(apt-cache madison geckodriver 2>/dev/null)" ]; then
    packages+=(geckodriver)
  fi
  if [ ${#packages[@]} -gt 0 ]; then apt_get install -y -q "${packages[@]}"; fi
  if ! command -v geckodriver >/dev/null; then cargo install geckodriver --locked; fi
fi
# The container tests (tests/container.rs) need a running Docker engine.
if ! docker info >/dev/null 2>&1; then
  echo "tests/run.sh: starting the Docker engine" >&2
  $sudo sh -c 'command -v service >/dev/null && service docker start' >&2 ||
    { $sudo sh -c 'nohup dockerd >/var/log/photonbox-dockerd.log 2>&1 &'; }
  for _ in $(seq 60); do docker info >/dev/null 2>&1 && break; sleep 1; done
  docker info >/dev/null
fi
# The API tests run schemathesis (PyPI) against a live server: into a virtual environment of
# its own, once per machine (pinned: its checks are what the test asserts).
st_venv="${PHOTONBOX_VENV:-$HOME/.cache/photonbox/venv}"
if [ ! -x "$st_venv/bin/st" ]; then
  echo "tests/run.sh: installing schemathesis into $st_venv" >&2
  python3 -m venv "$st_venv"
  "$st_venv/bin/pip" install -q "schemathesis==4.32.5"
fi
export PHOTONBOX_SCHEMATHESIS="$st_venv/bin/st"
"$PHOTONBOX_SCHEMATHESIS" --version
# Whole output (a `| head` would close the pipe early: geckodriver then panics on EPIPE and
# pipefail fails the run).
geckodriver --version
# Every test binary, even after one fails (cargo stops at the first failing binary otherwise).
# The library's, the binaries' and tests/'s tests: not the examples (benchmark harnesses;
# the clippy gate below still compiles them), to keep CI's compile short.
# (Tried and dropped, on two cores: building the container tests' image in the background
# while the tests compiled (29m57s against 29m10s), and only its base images (16m35s
# against 16m41s: the compile took 2 minutes longer, the container tests 2.4 less).)
cargo test --no-fail-fast --lib --bins --tests "$@"
# The lint gates, after the tests (CI runs this script and nothing else).
cargo fmt --check
cargo clippy --all-targets -- -D warnings
