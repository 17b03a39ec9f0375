# terrastitch in a container: a plain mirror of `make run`, listening on 0.0.0.0:8080.
# Build: docker build -t terrastitch .
# Run:   docker run -p 8080:8080 -v terrastitch-cache:/var/cache/terrastitch terrastitch

FROM rust:1-bookworm AS build
WORKDIR /src
COPY Cargo.toml Cargo.lock ./
COPY src ./src
COPY migrations ./migrations
COPY config ./config
RUN cargo build --release --locked

FROM debian:bookworm-slim
RUN apt-get update \
 && apt-get install -y --no-install-recommends ca-certificates curl \
 && rm -rf /var/lib/apt/lists/* \
 && useradd --system --home /srv/terrastitch terrastitch \
 && mkdir -p /srv/terrastitch /var/cache/terrastitch /srv/terrastitch/data \
 && chown terrastitch /var/cache/terrastitch
WORKDIR /srv/terrastitch
COPY --from=build /src/target/release/terrastitch /usr/local/bin/terrastitch
COPY config ./config
COPY data ./data
ENV TERRASTITCH_SERVER__LISTEN=0.0.0.0:8080 \
    TERRASTITCH_CACHE__PATH=/var/cache/terrastitch/tiles.sqlite
VOLUME ["/srv/terrastitch/data", "/var/cache/terrastitch"]
USER terrastitch
EXPOSE 8080
HEALTHCHECK --interval=30s --timeout=5s --start-period=20s \
  CMD curl -fsS http://127.0.0.1:8080/health || exit 1
CMD ["terrastitch", "serve"]
