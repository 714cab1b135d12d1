# Build and run the photonbox server. `docker build -t photonbox . && docker run -p 8080:8080 photonbox`
FROM rust:1-bookworm AS build
WORKDIR /src
COPY . .
RUN cargo build --release --locked

FROM debian:bookworm-slim
COPY --from=build /src/target/release/photonbox /usr/local/bin/photonbox
COPY --from=build /src/scenes /opt/photonbox/scenes
WORKDIR /opt/photonbox
EXPOSE 8080
CMD ["photonbox", "serve", "--addr", "0.0.0.0:8080", "--data", "/var/lib/photonbox"]
