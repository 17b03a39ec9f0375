// Loads the server's 3D Tiles tileset in NASA-AMMOS 3DTilesRendererJS (three.js) in headless
// Chromium and prints what it saw as one JSON object. The page and the libraries are answered
// by this script under the server's own origin (paths below /tiles3d-check/, which the server
// never sees); the tileset and its tiles come from the server.
// Usage: node tiles3d_check.mjs BASE_URL OUT_DIR LAT LON [TILESET]
//   BASE_URL  the server, e.g. http://127.0.0.1:8080/
//   OUT_DIR   where the screenshot goes
//   LAT LON   a building's centre: a ray straight down there must hit a building
//   TILESET   the tileset's path under BASE_URL (default 3dtiles/tileset.json?compress=meshopt)
import { animationFrames, launch, watch } from './browser.mjs';
import { readFile } from 'node:fs/promises';
import { join, dirname, extname } from 'node:path';
import { fileURLToPath } from 'node:url';

const [base, outDir, lat, lon, tilesetPath] = process.argv.slice(2);
const here = dirname(fileURLToPath(import.meta.url));
const prefix = `${base}tiles3d-check`;
const result = { consoleErrors: [], pageErrors: [] };

const page = `<!doctype html><html><body style="margin:0">
<script type="importmap">{"imports": {
  "three": "/tiles3d-check/node_modules/three/build/three.module.js",
  "three/addons/": "/tiles3d-check/node_modules/three/examples/jsm/",
  "3d-tiles-renderer": "/tiles3d-check/node_modules/3d-tiles-renderer/build/index.js",
  "3d-tiles-renderer/plugins": "/tiles3d-check/node_modules/3d-tiles-renderer/build/index.plugins.js"
}}</script>
<script type="module">
import * as THREE from 'three';
import { TilesRenderer, WGS84_ELLIPSOID } from '3d-tiles-renderer';
import { GLTFExtensionsPlugin } from '3d-tiles-renderer/plugins';
import { MeshoptDecoder } from 'three/addons/libs/meshopt_decoder.module.js';

const params = new URLSearchParams(location.search);
const lat = THREE.MathUtils.degToRad(Number(params.get('lat')));
const lon = THREE.MathUtils.degToRad(Number(params.get('lon')));
const renderer = new THREE.WebGLRenderer({ preserveDrawingBuffer: true });
renderer.setSize(800, 600);
document.body.appendChild(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x9db4cc);
scene.add(new THREE.HemisphereLight(0xffffff, 0x555555, 2.5));
const camera = new THREE.PerspectiveCamera(50, 800 / 600, 1, 1e7);
const tiles = new TilesRenderer(params.get('tileset'));
tiles.registerPlugin(new GLTFExtensionsPlugin({ meshoptDecoder: MeshoptDecoder }));
tiles.setCamera(camera);
tiles.setResolutionFromRenderer(camera, renderer);
scene.add(tiles.group);
const state = { loaded: [], errors: [], frames: 0 };
tiles.addEventListener('load-model', (e) => state.loaded.push(String(e.tile?.content?.uri ?? '')));
tiles.addEventListener('load-error', (e) => state.errors.push(String(e.error?.message ?? e.error) + ' ' + (e.url ?? '')));

// From 1,200 m above the point, looking at it from the south.
const at = (height, dLat = 0) => WGS84_ELLIPSOID.getCartographicToPosition(lat + dLat, lon, height, new THREE.Vector3());
camera.position.copy(at(1200, -0.00015));
camera.up.copy(at(1).sub(at(0)).normalize());
camera.lookAt(at(0));
// The camera stands still: a frame is drawn when the tiles shown change.
let dirty = true;
for (const type of ['load-model', 'dispose-model', 'tile-visibility-change']) {
  tiles.addEventListener(type, () => { dirty = true; });
}
function frame() {
  camera.updateMatrixWorld();
  tiles.update();
  if (dirty) {
    dirty = false;
    renderer.render(scene, camera);
    state.frames++;
  }
  requestAnimationFrame(frame);
}
frame();

window.check = {
  state,
  /** A ray straight down at the point: the node its first hit belongs to, and the height. */
  probe() {
    const from = at(2000);
    const ray = new THREE.Raycaster(from, at(0).sub(from).normalize());
    const hit = ray.intersectObject(tiles.group, true)[0];
    if (!hit) return null;
    let node = hit.object;
    const names = [];
    while (node) { if (node.name) names.push(node.name); node = node.parent; }
    const where = WGS84_ELLIPSOID.getPositionToCartographic(hit.point, {});
    return { names, height: where.height, dLat: where.lat - lat, dLon: where.lon - lon };
  },
  busy: () => tiles.stats.downloading + tiles.stats.parsing,
};
</script></body></html>`;

const types = { '.js': 'text/javascript', '.mjs': 'text/javascript', '.json': 'application/json' };
const browser = await launch();
try {
  const context = await browser.newContext({ viewport: { width: 480, height: 360 } });
  await context.route(`${prefix}/**`, async (route) => {
    const path = new URL(route.request().url()).pathname.replace(/^\/tiles3d-check/, '');
    if (path === '/' || path === '') {
      await route.fulfill({ contentType: 'text/html', body: page });
    } else if (path.startsWith('/node_modules/') && !path.includes('..')) {
      try {
        const body = await readFile(join(here, path));
        await route.fulfill({ contentType: types[extname(path)] ?? 'application/octet-stream', body });
      } catch (error) {
        await route.fulfill({ status: 404, body: String(error) });
      }
    } else {
      await route.fulfill({ status: 404, body: 'not found' });
    }
  });
  const tab = await context.newPage();
  watch(tab, result);
  result.failedResponses = [];
  tab.on('response', (r) => {
    if (r.status() >= 400) result.failedResponses.push(`${r.status()} ${r.url()}`);
  });
  // In the folder of the files it names: 3DTilesRendererJS cuts a tileset's URL at the last
  // slash and adds one, which at a server's root gives `//`.
  const tileset = `${base}${tilesetPath ?? '3dtiles/tileset.json?compress=meshopt'}`;
  const started = Date.now();
  await tab.goto(`${prefix}/?tileset=${encodeURIComponent(tileset)}&lat=${lat}&lon=${lon}`);
  await tab.waitForFunction(() => window.check
    && window.check.state.loaded.filter((u) => u.includes('.glb')).length >= 4
    && window.check.busy() === 0, null, { timeout: 240000, polling: 250 });
  result.settledMs = Date.now() - started;
  await animationFrames(tab);
  result.state = await tab.evaluate(() => window.check.state);
  result.probe = await tab.evaluate(() => window.check.probe());
  await tab.screenshot({ path: join(outDir, 'tiles3d-renderer.png') });
} catch (error) {
  result.error = String(error.stack ?? error);
} finally {
  await browser.close();
}
console.log(JSON.stringify(result));
