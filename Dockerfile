# photonbox render server: multi-stage build, slim runtime, non-root, data volume.
#
#   docker build -t photonbox .
#   docker run -p 8080:8080 -v photonbox-data:/data photonbox
#
# The admin sign-in URL is printed in the container's log (docker logs).

FROM rust:1.95-slim-bookworm AS build
WORKDIR /src
# gcc for rusqlite's bundled SQLite.
RUN apt-get update && apt-get install -y --no-install-recommends gcc libc6-dev \
    && rm -rf /var/lib/apt/lists/*
COPY Cargo.toml Cargo.lock ./
COPY src src
COPY benches benches
COPY examples examples
COPY web web
COPY scenes scenes
RUN cargo build --release --locked --bin photonbox \
    && strip target/release/photonbox

FROM debian:bookworm-slim
RUN apt-get update && apt-get install -y --no-install-recommends curl ca-certificates \
    && rm -rf /var/lib/apt/lists/* \
    && useradd --system --uid 10001 --home-dir /data photonbox \
    && mkdir -p /data && chown photonbox /data
COPY --from=build /src/target/release/photonbox /usr/local/bin/photonbox
COPY --from=build /src/scenes /opt/photonbox/scenes
USER photonbox
VOLUME ["/data"]
EXPOSE 8080
HEALTHCHECK --interval=30s --timeout=3s --start-period=5s \
    CMD curl -fsS http://127.0.0.1:8080/healthz || exit 1
ENTRYPOINT ["photonbox", "serve", "--addr", "0.0.0.0:8080", "--data", "/data", "--scenes", "/opt/photonbox/scenes"]
