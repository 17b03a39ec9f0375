# terrastitch in a container: a plain mirror of `make run`, listening on 0.0.0.0:8080, run as
# an unprivileged user, with the data directory (sources and their downloads) and the tile
# cache on volumes. SIGTERM (docker stop) lets the renders in flight finish.
# Build: docker build -t terrastitch .
# Run:   docker run -p 8080:8080 -v terrastitch-data:/srv/terrastitch/data \
#          -v terrastitch-cache:/var/cache/terrastitch terrastitch
# Seed:  docker run -v ... terrastitch terrastitch seed --bbox 7.40,43.72,7.44,43.75

FROM rust:1-bookworm AS build
WORKDIR /src
COPY Cargo.toml Cargo.lock ./
COPY src ./src
COPY migrations ./migrations
COPY config ./config
RUN cargo build --release --locked

# The viewer's libraries, from npm with the lock file (what `make run` copies into static/vendor).
FROM node:20-bookworm-slim AS viewer
WORKDIR /viewer
COPY viewer/package.json viewer/package-lock.json ./
RUN npm ci --no-audit --no-fund

FROM debian:bookworm-slim
RUN apt-get update \
 && apt-get install -y --no-install-recommends ca-certificates curl \
 && rm -rf /var/lib/apt/lists/* \
 && useradd --system --home /srv/terrastitch terrastitch \
 && mkdir -p /srv/terrastitch /var/cache/terrastitch /srv/terrastitch/data \
 && chown terrastitch /var/cache/terrastitch /srv/terrastitch/data
WORKDIR /srv/terrastitch
COPY --from=build /src/target/release/terrastitch /usr/local/bin/terrastitch
COPY config ./config
COPY static ./static
COPY --from=viewer /viewer/node_modules/three/build ./static/vendor/three/build
COPY --from=viewer /viewer/node_modules/three/examples/jsm ./static/vendor/three/examples/jsm
COPY --from=viewer /viewer/node_modules/three/LICENSE ./static/vendor/three/LICENSE
COPY --from=viewer /viewer/node_modules/cesium/Build/Cesium ./static/vendor/cesium
COPY --from=viewer /viewer/node_modules/cesium/LICENSE.md ./static/vendor/cesium/LICENSE.md
# The sample; downloads (sources.downloads = data/downloads) go into the same volume.
COPY --chown=terrastitch data ./data
ENV TERRASTITCH_SERVER__LISTEN=0.0.0.0:8080 \
    TERRASTITCH_CACHE__PATH=/var/cache/terrastitch/tiles.sqlite
VOLUME ["/srv/terrastitch/data", "/var/cache/terrastitch"]
USER terrastitch
EXPOSE 8080
HEALTHCHECK --interval=30s --timeout=5s --start-period=20s \
  CMD curl -fsS http://127.0.0.1:8080/health || exit 1
CMD ["terrastitch", "serve"]
