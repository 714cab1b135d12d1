#!/usr/bin/env bash
# Builds the Dockerfile's image as the container tests use it: photonbox:container-test, from
# the base images of base-images.sh, with PROFILE=quick (tests/container.rs runs it; run
# again, Docker's build cache answers at once).
set -euo pipefail
cd "$(dirname "$0")/../.."
tests/docker/base-images.sh
docker build -q -t photonbox:container-test \
  --build-arg BUILD_IMAGE=photonbox/rust:bookworm \
  --build-arg RUNTIME_IMAGE=photonbox/debian:bookworm \
  --build-arg PROFILE=quick . >/dev/null
