# terrastitch: `make run` serves the bundled Monaco sample on http://127.0.0.1:8080,
# `make test` runs every check and test; `make check` is the fast tier (under two minutes once
# built): formatting, lints, unit tests, the layering test and the rule specifications.

CARGO ?= cargo
NPM ?= npm
# Tests at once: many of them wait on a server, a browser or a database process, so more than
# the cores keeps the cores busy.
TEST_THREADS ?= 4

.PHONY: run test check lint bench bench-hardening bench-terrain bench-roofs bench-tile bench-elevation bench-scale bench-cluster clean-cache

run: static/vendor/.installed
	$(CARGO) run --release -- serve

# The viewers' libraries (three.js for the flat viewer, CesiumJS for the globe), pinned by the
# lock file and copied next to the pages:
# nothing is fetched from a CDN when the page loads.
static/vendor/.installed: viewer/package.json viewer/package-lock.json
	cd viewer && $(NPM) ci --no-audit --no-fund
	rm -rf static/vendor && mkdir -p static/vendor/three/examples
	cp -r viewer/node_modules/three/build static/vendor/three/build
	cp -r viewer/node_modules/three/examples/jsm static/vendor/three/examples/jsm
	cp viewer/node_modules/three/LICENSE static/vendor/three/LICENSE
	cp -r viewer/node_modules/cesium/Build/Cesium static/vendor/cesium
	cp viewer/node_modules/cesium/LICENSE.md static/vendor/cesium/LICENSE.md
	touch $@

# Chromium for the tests in a real browser (Debian's package), unless one is installed.
tests/.chromium:
	command -v chromium >/dev/null || (apt-get update && apt-get install -y --no-install-recommends chromium)
	touch $@

# PostgreSQL's server programs for the tests of the shared tile cache (Debian's package), unless
# installed; the tests start a throwaway cluster of their own. PostgreSQL refuses to run as
# root: as root, the tests run it as the unprivileged user terrastitch-pg, created here.
tests/.postgresql:
	ls /usr/lib/postgresql/*/bin/initdb >/dev/null 2>&1 || command -v initdb >/dev/null || \
		(apt-get update && apt-get install -y --no-install-recommends postgresql)
	if [ "$$(id -u)" = 0 ] && ! id terrastitch-pg >/dev/null 2>&1; then \
		useradd --system --no-create-home --shell /usr/sbin/nologin terrastitch-pg; fi
	touch $@

test: tests/js/node_modules/.installed tests/py/.venv/.installed static/vendor/.installed tests/.chromium tests/.postgresql lint
	TERRASTITCH_PYTHON=$(CURDIR)/tests/py/.venv/bin/python $(CARGO) test --release -- --test-threads=$(TEST_THREADS)

# The fast tier: no extract read, no browser, no server process.
check: lint
	$(CARGO) test --release --lib
	$(CARGO) test --release --test integration -- layers:: spec:: rules:: router::

lint:
	$(CARGO) fmt --all -- --check
	$(CARGO) clippy --release --all-targets -- -D warnings

# Node tools the tests use (the Khronos glTF validator), pinned by the lock file.
tests/js/node_modules/.installed: tests/js/package.json tests/js/package-lock.json
	cd tests/js && $(NPM) ci --no-audit --no-fund
	touch $@

# Python tools the tests use (numpy for the quantized-mesh checker, a second reader), pinned.
tests/py/.venv/.installed: tests/py/requirements.txt
	python3 -m venv tests/py/.venv
	tests/py/.venv/bin/python -m pip install --quiet --disable-pip-version-check -r tests/py/requirements.txt
	touch $@

# Server figures: one tile's cold render; cached requests per second and latency on loopback;
# a cold burst of 200 requests over 20 tiles; seeding and exporting the sample's area
# (needs `wrk` on the PATH).
bench: tests/py/.venv/.installed
	$(CARGO) build --release
	scripts/bench.sh

# Terrain figures: greedy insertion against pydelatin and pymartini on windows of the SRTM files
# (every mesh checked by the same error measure), and least squares against natural neighbour.
bench-terrain: tests/py/.venv/.installed
	$(CARGO) build --release --examples
	tests/py/.venv/bin/python -m pip install --quiet --disable-pip-version-check -r tests/py/requirements-bench.txt
	tests/py/.venv/bin/python scripts/terrain_compare.py tests/data/N48E009.hgt data/N43E007.hgt --windows win257,crop1025
	target/release/examples/approximation_compare tests/data/N48E009.hgt

# Roof figures: building shells per second over the Monaco tiles of both extracts, with the
# roofs as tagged and with every footprint given one shape, and the roofs that fell back.
# Country scale: import, serve and render on extracts of 1, 100 and 400 copies of Monaco
# (COPIES="1 25" for others); the extracts are made once into target/scale/.
# A hostile client's figures: concurrent debug views, dropped requests, half-sent requests and
# shutdown (loopback, the bundled sample); then one road node moved far away by a diff: the
# time and memory of `update` and of the next render, at each distance.
bench-hardening: tests/py/.venv/.installed
	$(CARGO) build --release
	tests/py/.venv/bin/python scripts/bench_hardening.py

bench-scale: tests/py/.venv/.installed
	$(CARGO) build --release
	tests/py/.venv/bin/python -m pip install --quiet --disable-pip-version-check -r tests/py/requirements-bench.txt
	scripts/bench_scale.sh $(COPIES)

# Several processes on one PostgreSQL database: cold tiles over 1, 2 and 3 replicas, cached
# reads against SQLite, seeding with 1 and 2 workers, size per stored tile.
bench-cluster: tests/.postgresql
	$(CARGO) build --release
	python3 scripts/bench_cluster.py

bench-roofs:
	$(CARGO) build --release --examples
	for osm in data/monaco-osrm-2016.osm.pbf tests/data/monaco-planetiler-2021.osm.pbf; do \
	  for shape in tagged hipped gabled skillion; do \
	    target/release/examples/roof_bench $$osm data $$shape || exit 1; \
	  done; \
	done

# Elevation LP figures: solve times on problems shaped like a tile's, 1k to 50k stations.
# The cost of one tile: the densest tile cold and warm by stage, every tile of the bundled
# extract cold (mean, p95). BASE=path/to/another/terrastitch measures it alongside.
bench-tile:
	$(CARGO) build --release
	python3 scripts/bench_tile.py $(if $(BASE),--base $(BASE))

bench-elevation:
	$(CARGO) build --release --examples
	target/release/examples/lp_bench

clean-cache:
	rm -rf cache
