// The terrastitch viewer: streams the zoom-14 glb tiles around the camera and places each by
// translation in one shared Web Mercator frame, where neighbours meet exactly. Farther away it
// draws the server's coarser tiles for far views (zooms 13, 12, 10, 8, as `/tiles.json` lists
// them in `far_zooms`): the tiles drawn are the leaves of a quadtree split wherever a tile is
// near the camera for its size, and a tile not yet loaded is stood in for by its nearest loaded
// ancestor, so the view is never empty where data is.
//
// World frame: x east and z south in Web Mercator metres from the north-west corner of the
// origin tile, y up (elevation times the Mercator scale factor, as in the tiles).

import * as THREE from 'three';
import { MapControls } from 'three/addons/controls/MapControls.js';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { MeshoptDecoder } from 'three/addons/libs/meshopt_decoder.module.js';
import { Sky } from 'three/addons/objects/Sky.js';

const ZOOM = 14;
const EARTH_CIRCUMFERENCE_M = 40075016.68557849;
const TILE_M = EARTH_CIRCUMFERENCE_M / 2 ** ZOOM;
const TILES_PER_AXIS = 2 ** ZOOM;
/** What the server says of its tiles (`/tiles.json`): where its data is, which compressions. */
const DESCRIPTION = await fetch('tiles.json')
  .then((response) => (response.ok ? response.json() : null))
  .catch(() => null);
/** Where the page opens when its URL names no place: the centre of the server's data (Monte-Carlo
 * in the bundled sample, and when the server does not say). */
const START = (() => {
  const view = { lat: 43.7396, lon: 7.4255, distance: 1800, heading: 20, tilt: 50 };
  const [lon, lat] = DESCRIPTION?.center ?? [];
  return Number.isFinite(lon) && Number.isFinite(lat) && Math.abs(lat) <= 85
    ? { ...view, lat, lon } : view;
})();
/** The zooms drawn, coarsest first: the server's far views, then its tiles. */
const LEVELS = [
  ...(Array.isArray(DESCRIPTION?.far_zooms) ? DESCRIPTION.far_zooms : [])
    .filter((z) => Number.isInteger(z) && z < ZOOM)
    .sort((a, b) => a - b),
  ZOOM,
];
/** A tile is split into the next level's while the camera's distance to the point looked at,
 * plus the distance from that point to the tile, is under this many times the tile's size. */
const SPLIT = 0.8;
/** Tiles kept loaded; the least recently wanted beyond this are dropped and their GPU memory freed. */
const MAX_LOADED = 64;
/** Tile requests in flight at once. */
const MAX_FETCHES = 4;

// ---------------------------------------------------------------------------------------
// Coordinates

function lonLatToUV(lon, lat) {
  const phi = (lat * Math.PI) / 180;
  const u = ((lon + 180) / 360) * TILES_PER_AXIS;
  const v = ((1 - Math.log(Math.tan(phi) + 1 / Math.cos(phi)) / Math.PI) / 2) * TILES_PER_AXIS;
  return [u, v];
}

function uvToLonLat(u, v) {
  const lon = (u / TILES_PER_AXIS) * 360 - 180;
  const n = Math.PI - (2 * Math.PI * v) / TILES_PER_AXIS;
  const lat = (180 / Math.PI) * Math.atan(Math.sinh(n));
  return [lon, lat];
}

/** The origin tile: the world frame's (0, 0) is its north-west corner. */
const origin = (() => {
  const view = parseHash() || START;
  const [u, v] = lonLatToUV(view.lon, view.lat);
  return { x: Math.floor(u), y: Math.floor(v) };
})();

function worldFromLonLat(lon, lat, elevation = 0) {
  const [u, v] = lonLatToUV(lon, lat);
  const scale = 1 / Math.cos((lat * Math.PI) / 180);
  return new THREE.Vector3((u - origin.x) * TILE_M, elevation * scale, (v - origin.y) * TILE_M);
}

function lonLatFromWorld(p) {
  return uvToLonLat(p.x / TILE_M + origin.x, p.z / TILE_M + origin.y);
}

// ---------------------------------------------------------------------------------------
// Scene

const container = document.getElementById('map');
const renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(Math.min(window.devicePixelRatio, 2));
renderer.setSize(container.clientWidth, container.clientHeight);
renderer.toneMapping = THREE.ACESFilmicToneMapping;
renderer.toneMappingExposure = 0.6;
container.appendChild(renderer.domElement);

const scene = new THREE.Scene();
// A frame is drawn only when something changed (the camera, a tile, a layer, the size): an
// idle view costs nothing, on a laptop's battery or in software WebGL.
let redraw = true;
function invalidate() {
  redraw = true;
}
scene.fog = new THREE.Fog(0xc9d6e3, 6000, 16000);
const camera = new THREE.PerspectiveCamera(45, container.clientWidth / container.clientHeight, 2, 400000);

const sunDirection = new THREE.Vector3();
// The sun, with soft shadows over the 3 km around the point looked at (a 4096² map: 0.7 m a
// texel), when the page draws on a GPU; software WebGL starts without them (they halve its
// frame rate), and the layer box turns them on or off.
const sun = new THREE.DirectionalLight(0xfff4e0, 2.4);
const SHADOW_REACH_M = 1500;
{
  const shadow = sun.shadow;
  shadow.mapSize.set(4096, 4096);
  Object.assign(shadow.camera, {
    left: -SHADOW_REACH_M, right: SHADOW_REACH_M, top: SHADOW_REACH_M, bottom: -SHADOW_REACH_M,
    near: 10, far: 10000,
  });
  shadow.camera.updateProjectionMatrix();
  shadow.bias = -0.0004;
  shadow.normalBias = 0.8;
  renderer.shadowMap.type = THREE.PCFShadowMap;
}

/** Whether WebGL runs in software here (SwiftShader, llvmpipe). */
function softwareRendering() {
  const gl = renderer.getContext();
  const info = gl.getExtension('WEBGL_debug_renderer_info');
  const name = info ? String(gl.getParameter(info.UNMASKED_RENDERER_WEBGL)) : '';
  return /swiftshader|llvmpipe|software/i.test(name);
}

function setShadows(on) {
  invalidate();
  renderer.shadowMap.enabled = on;
  sun.castShadow = on;
  // Materials compiled without shadows need compiling again.
  scene.traverse((o) => {
    const materials = Array.isArray(o.material) ? o.material : o.material ? [o.material] : [];
    for (const m of materials) m.needsUpdate = true;
  });
}

/** Keeps the sun and its shadow box over the point looked at. */
function followSun(target) {
  sun.target.position.copy(target);
  sun.position.copy(target).addScaledVector(sunDirection, 5000);
}
{
  const elevation = THREE.MathUtils.degToRad(40);
  const azimuth = THREE.MathUtils.degToRad(210);
  // Compass azimuth (clockwise from north) in a frame of x east, z south: theta = pi - azimuth.
  sunDirection.setFromSphericalCoords(1, Math.PI / 2 - elevation, Math.PI - azimuth);
  const sky = new Sky();
  sky.scale.setScalar(100000);
  const uniforms = sky.material.uniforms;
  uniforms.turbidity.value = 6;
  uniforms.rayleigh.value = 1.2;
  uniforms.sunPosition.value.copy(sunDirection);
  scene.add(sky);
  scene.add(sun);
  scene.add(sun.target);
  scene.add(new THREE.HemisphereLight(0xbfd6ff, 0x6b5e4a, 1.1));
}

const controls = new MapControls(camera, renderer.domElement);
controls.enableDamping = true;
controls.dampingFactor = 0.12;
controls.screenSpacePanning = false;
controls.maxPolarAngle = THREE.MathUtils.degToRad(85);
controls.minDistance = 30;
// Far enough to see a whole region where the server draws far views.
controls.maxDistance = LEVELS.length > 1 ? 150000 : 12000;

function setView(view) {
  const target = worldFromLonLat(view.lon, view.lat, view.elevation ?? 60);
  const tilt = THREE.MathUtils.degToRad(view.tilt);
  const heading = THREE.MathUtils.degToRad(view.heading);
  const offset = new THREE.Vector3(
    Math.sin(tilt) * Math.sin(heading),
    Math.cos(tilt),
    Math.sin(tilt) * Math.cos(heading),
  ).multiplyScalar(view.distance);
  controls.target.copy(target);
  camera.position.copy(target).add(offset);
  controls.update();
}

// Thin or hollow things the view does not stand on.
const SKIPPED_NODES = /^(tunnel|power|barrier|marking)/;
const downward = new THREE.Raycaster();

/** The height of the top of what is drawn under a point of the world (the ground, or a roof:
 *  the ground under a building is not drawn) in the finest loaded tiles, or null where none
 *  is loaded. */
function groundUnder(x, z) {
  const ground = [];
  for (const tile of tiles.values()) {
    if (tile.state !== 'loaded' || !tile.group || tile.z !== ZOOM || !holds(tile, { x, z })) continue;
    tile.group.updateMatrixWorld();
    tile.group.traverse((o) => {
      if (o.isMesh && !o.isInstancedMesh && !SKIPPED_NODES.test(o.name) && !SKIPPED_NODES.test(o.parent?.name ?? '')) {
        ground.push(o);
      }
    });
  }
  if (ground.length === 0) return null;
  downward.set(new THREE.Vector3(x, 1e5, z), new THREE.Vector3(0, -1, 0));
  return downward.intersectObjects(ground, false)[0]?.point.y ?? null;
}

/** Whether a loaded tile's square holds the point `p` of the world, seen from above. */
function holds(tile, p) {
  const size = span(tile.z) * TILE_M;
  const corner = tile.group.position;
  return p.x >= corner.x && p.x <= corner.x + size && p.z >= corner.z && p.z <= corner.z + size;
}

/** Least height of the camera over the ground, metres. */
const CAMERA_CLEARANCE = 2;

/** Puts the view's target on the ground drawn under it, moving the camera with it, and keeps
 *  the camera above the ground, so a view set or panned over high or steep ground does not
 *  look at it from below. */
function settleOnGround() {
  const target = controls.target;
  const ground = groundUnder(target.x, target.z);
  if (ground === null) return;
  const rise = ground - target.y;
  if (Math.abs(rise) > 0.5) {
    target.y += rise;
    camera.position.y += rise;
  }
  const under = groundUnder(camera.position.x, camera.position.z);
  if (under !== null && camera.position.y < under + CAMERA_CLEARANCE) {
    camera.position.y = under + CAMERA_CLEARANCE;
  }
  controls.update();
  invalidate();
}

function currentView() {
  const [lon, lat] = lonLatFromWorld(controls.target);
  const offset = camera.position.clone().sub(controls.target);
  const distance = offset.length();
  return {
    lat,
    lon,
    distance,
    heading: THREE.MathUtils.radToDeg(Math.atan2(offset.x, offset.z)),
    tilt: THREE.MathUtils.radToDeg(Math.acos(THREE.MathUtils.clamp(offset.y / distance, -1, 1))),
  };
}

// ---------------------------------------------------------------------------------------
// The location in the URL: #lat,lon,distance,heading,tilt

function parseHash() {
  const parts = location.hash.replace(/^#/, '').split(',').map(Number);
  if (parts.length < 2 || parts.slice(0, 2).some((n) => !Number.isFinite(n))) return null;
  const [lat, lon, distance, heading, tilt] = parts;
  if (Math.abs(lat) > 85 || Math.abs(lon) > 180) return null;
  return {
    lat,
    lon,
    distance: Number.isFinite(distance) ? distance : START.distance,
    heading: Number.isFinite(heading) ? heading : START.heading,
    tilt: Number.isFinite(tilt) ? tilt : START.tilt,
  };
}

let hashTimer = null;
function writeHash() {
  clearTimeout(hashTimer);
  hashTimer = setTimeout(() => {
    const v = currentView();
    const hash = `#${v.lat.toFixed(5)},${v.lon.toFixed(5)},${Math.round(v.distance)},${Math.round(v.heading)},${Math.round(v.tilt)}`;
    if (hash !== location.hash) history.replaceState(null, '', hash);
  }, 300);
}

window.addEventListener('hashchange', () => {
  const view = parseHash();
  if (view) jumpTo(view);
});

function jumpTo(view) {
  const far = lonLatToUV(view.lon, view.lat).some((t, i) => Math.abs(t - [origin.x, origin.y][i]) > 200);
  if (far) {
    // Far from the origin, floats lose precision: start again there.
    location.hash = `#${view.lat},${view.lon},${view.distance},${view.heading},${view.tilt}`;
    location.reload();
    return;
  }
  setView(view);
  settleOnGround();
  scheduleTiles();
}

// ---------------------------------------------------------------------------------------
// Tiles

// Tiles come compressed (EXT_meshopt_compression over KHR_mesh_quantization, about a quarter
// of the bytes) unless the page's query says `?compress=none`, or the server does not offer
// it (a server of an archive offers the compression the archive holds).
const COMPRESS = (() => {
  const wanted = new URLSearchParams(window.location.search).get('compress') === 'none'
    ? 'none' : 'meshopt';
  // Without a description, ask for what the page wants.
  const offered = DESCRIPTION?.glb_compressions;
  if (Array.isArray(offered) && offered.length > 0 && !offered.includes(wanted)) return offered[0];
  return wanted;
})();
const loader = new GLTFLoader();
loader.setMeshoptDecoder(MeshoptDecoder);

/** key "z/x/y" → { z, x, y, state: 'queued' | 'loading' | 'loaded' | 'failed', group, table,
 * wanted } */
const tiles = new Map();
let fetching = 0;
let wantedStamp = 0;

/** What the tests (and a curious person in the console) can read. */
const stats = { requested: [], loaded: [], failed: [], frames: 0, firstFullView: null };
const started = performance.now();

const statusBox = document.getElementById('status');
const errorBox = document.getElementById('errors');

function showStatus() {
  const loading = [...tiles.values()].filter((t) => t.state === 'loading').length;
  statusBox.textContent = loading ? `Loading ${loading} tile${loading > 1 ? 's' : ''}…` : '';
}

function showError(message) {
  errorBox.textContent = message;
  clearTimeout(showError.timer);
  showError.timer = setTimeout(() => { errorBox.textContent = ''; }, 8000);
}

/** Zoom-14 tile units per tile of zoom `z`. */
function span(z) {
  return 2 ** (ZOOM - z);
}

function keyOf(tile) {
  return `${tile.z}/${tile.x}/${tile.y}`;
}

/** Whether a tile of zoom `z` meets the server's data (far views are made only there). */
function meetsData(z, x, y) {
  const bounds = DESCRIPTION?.bounds;
  if (!Array.isArray(bounds) || bounds.length < 4) return true;
  const f = span(z);
  const [west, north] = uvToLonLat(x * f, y * f);
  const [east, south] = uvToLonLat((x + 1) * f, (y + 1) * f);
  return west < bounds[2] && east > bounds[0] && south < bounds[3] && north > bounds[1];
}

/** The tiles to draw, nearest first (`d`: the distance from the point looked at to the tile, in
 * zoom-14 tiles): the leaves of the quadtree over LEVELS around the camera's target. With no
 * far views, the zoom-14 tiles within one to three tiles, by the camera's distance. */
function wantedTiles() {
  const [u, v] = [controls.target.x / TILE_M + origin.x, controls.target.z / TILE_M + origin.y];
  const distance = camera.position.distanceTo(controls.target);
  const wanted = [];
  const nearest = (z, x, y) => {
    const f = span(z);
    const dx = Math.max(x * f - u, 0, u - (x + 1) * f);
    const dy = Math.max(y * f - v, 0, v - (y + 1) * f);
    return Math.hypot(dx, dy);
  };
  const visit = (level, x, y) => {
    const z = LEVELS[level];
    const limit = 2 ** z;
    if (x < 0 || y < 0 || x >= limit || y >= limit) return;
    if (z < ZOOM && !meetsData(z, x, y)) return;
    const d = nearest(z, x, y);
    const next = LEVELS[level + 1];
    if (next !== undefined && d * TILE_M + distance < SPLIT * span(z) * TILE_M) {
      const k = 2 ** (next - z);
      for (let dy = 0; dy < k; dy++) {
        for (let dx = 0; dx < k; dx++) visit(level + 1, x * k + dx, y * k + dy);
      }
      return;
    }
    wanted.push({ z, x, y, d });
  };
  const top = LEVELS[0];
  const radius = top === ZOOM ? THREE.MathUtils.clamp(Math.ceil(distance / TILE_M), 1, 3) : 1;
  const cx = Math.floor(u / span(top));
  const cy = Math.floor(v / span(top));
  for (let y = cy - radius; y <= cy + radius; y++) {
    for (let x = cx - radius; x <= cx + radius; x++) {
      if (top === ZOOM) {
        const d = Math.hypot(x + 0.5 - u, y + 0.5 - v);
        if (x >= 0 && y >= 0 && x < TILES_PER_AXIS && y < TILES_PER_AXIS) wanted.push({ z: ZOOM, x, y, d });
      } else {
        visit(0, x, y);
      }
    }
  }
  // The zoom-14 tile under the target and its eight neighbours first (the view is whole once
  // they are in), then nearest first; at one distance (the tiles around the target) the finest
  // first.
  const [tx, ty] = [Math.floor(u), Math.floor(v)];
  const later = (t) => (isAround(t, tx, ty) ? 0 : 1);
  return wanted.sort((a, b) => later(a) - later(b) || a.d - b.d || b.z - a.z);
}

/** Whether `tile` is the zoom-14 tile (`cx`, `cy`) or one of its eight neighbours. */
function isAround(tile, cx, cy) {
  return tile.z === ZOOM && Math.abs(tile.x - cx) <= 1 && Math.abs(tile.y - cy) <= 1;
}

/** The nearest loaded ancestor of a tile among the levels drawn, or null. */
function loadedAncestor(tile) {
  for (let level = LEVELS.indexOf(tile.z) - 1; level >= 0; level--) {
    const z = LEVELS[level];
    const f = 2 ** (tile.z - z);
    const held = tiles.get(`${z}/${Math.floor(tile.x / f)}/${Math.floor(tile.y / f)}`);
    if (held?.state === 'loaded') return held;
  }
  return null;
}

/** Shows each wanted tile that is loaded, and for one that is not, its nearest loaded ancestor
 * (kept from eviction); hides every tile under a shown ancestor, and the rest. */
function updateVisibility(wanted) {
  const shown = new Set();
  for (const w of wanted) {
    const tile = tiles.get(keyOf(w));
    if (tile?.state === 'loaded') {
      shown.add(keyOf(tile));
      continue;
    }
    const ancestor = loadedAncestor(w);
    if (ancestor) {
      ancestor.wanted = wantedStamp;
      shown.add(keyOf(ancestor));
    }
  }
  for (const tile of tiles.values()) {
    if (!tile.group) continue;
    const covered = loadedAncestor(tile);
    tile.group.visible = shown.has(keyOf(tile))
      && !(covered && shown.has(keyOf(covered)));
  }
  // Fog recedes as the camera draws back, so far views are not lost in it.
  const distance = camera.position.distanceTo(controls.target);
  scene.fog.near = Math.max(6000, distance * 2);
  scene.fog.far = Math.max(16000, distance * 6);
}

function scheduleTiles() {
  wantedStamp++;
  const wanted = wantedTiles();
  for (const w of wanted) {
    const key = keyOf(w);
    let tile = tiles.get(key);
    if (!tile) {
      tile = { z: w.z, x: w.x, y: w.y, state: 'queued', group: null, table: null };
      tiles.set(key, tile);
    }
    tile.wanted = wantedStamp;
  }
  for (const w of wanted) {
    if (fetching >= MAX_FETCHES) break;
    const tile = tiles.get(keyOf(w));
    if (tile.state === 'queued') loadTile(tile);
  }
  updateVisibility(wanted);
  evict();
  showStatus();
  invalidate();
}

async function loadTile(tile) {
  tile.state = 'loading';
  fetching++;
  // The request's place is given up once its body is in: the server goes on with the next
  // tile while this one is parsed.
  let fetchHeld = true;
  const release = () => {
    if (fetchHeld) {
      fetchHeld = false;
      fetching--;
    }
  };
  const url = `tiles/${keyOf(tile)}.glb?compress=${COMPRESS}`;
  stats.requested.push(keyOf(tile));
  showStatus();
  try {
    const response = await fetch(url);
    if (!response.ok) {
      let message = response.statusText;
      try {
        message = (await response.json()).error || message;
      } catch (_) {
        // Not JSON: keep the status text.
      }
      throw new Error(`tile ${keyOf(tile)}: ${response.status} ${message}`);
    }
    const body = await response.arrayBuffer();
    release();
    scheduleTiles();
    const gltf = await loader.parseAsync(body, '');
    const group = gltf.scene;
    const f = span(tile.z);
    group.position.set((tile.x * f - origin.x) * TILE_M, 0, (tile.y * f - origin.y) * TILE_M);
    group.visible = false;
    group.userData.tile = tile;
    tile.table = await propertyTable(gltf.parser);
    if (!tiles.has(keyOf(tile))) {
      dispose(group);
      return;
    }
    tile.group = group;
    tile.state = 'loaded';
    paintOverRoads(group);
    registerClasses(group);
    applyToggles(group);
    scene.add(group);
    stats.loaded.push(keyOf(tile));
    // Only a finest tile under the point looked at or under the camera can change where they
    // stand (reading the ground casts a ray through every triangle of the tile under a point).
    if (tile.z === ZOOM && (holds(tile, controls.target) || holds(tile, camera.position))) {
      settleOnGround();
    }
    if (layers.debug && tile.z === ZOOM) addDebug(tile);
    checkFirstView();
  } catch (error) {
    tile.state = 'failed';
    stats.failed.push({ tile: keyOf(tile), error: String(error.message || error) });
    showError(String(error.message || error));
  } finally {
    release();
    scheduleTiles();
  }
}

/** Drops the least recently wanted tiles beyond MAX_LOADED, freeing their GPU memory. */
function evict() {
  const held = [...tiles.entries()].filter(([, t]) => t.state === 'loaded' || t.state === 'failed');
  if (held.length <= MAX_LOADED) {
    // Queued tiles no longer wanted are forgotten at once.
    for (const [key, t] of tiles) if (t.state === 'queued' && t.wanted !== wantedStamp) tiles.delete(key);
    return;
  }
  held.sort((a, b) => a[1].wanted - b[1].wanted);
  for (const [key, tile] of held.slice(0, held.length - MAX_LOADED)) {
    if (tile.wanted === wantedStamp) break;
    if (tile.group) {
      scene.remove(tile.group);
      dispose(tile.group);
    }
    if (tile.debug) {
      scene.remove(tile.debug);
      dispose(tile.debug);
    }
    tiles.delete(key);
  }
}

// Road paint lies 3 cm over the road: drawn with a depth offset, it stays on top of the road
// from every distance instead of flickering through it.
function paintOverRoads(group) {
  group.traverse((o) => {
    const materials = Array.isArray(o.material) ? o.material : o.material ? [o.material] : [];
    for (const m of materials) {
      if (m.name === 'marking' || m.name === 'crossing') {
        m.polygonOffset = true;
        m.polygonOffsetFactor = -2;
        m.polygonOffsetUnits = -2;
      }
    }
  });
}

function dispose(object) {
  object.traverse((o) => {
    if (o.geometry) o.geometry.dispose();
    const materials = Array.isArray(o.material) ? o.material : o.material ? [o.material] : [];
    for (const m of materials) {
      for (const value of Object.values(m)) if (value && value.isTexture) value.dispose();
      m.dispose();
    }
  });
}

function checkFirstView() {
  if (stats.firstFullView !== null) return;
  // The nine zoom-14 tiles around the one under the point looked at, those of them drawn
  // (or, in a far view, the nine nearest tiles drawn).
  const wanted = wantedTiles();
  const cx = Math.floor(controls.target.x / TILE_M + origin.x);
  const cy = Math.floor(controls.target.z / TILE_M + origin.y);
  const around = wanted.filter((t) => isAround(t, cx, cy));
  const start = around.length > 0 ? around : wanted.slice(0, 9);
  if (start.length > 0 && start.every((t) => tiles.get(keyOf(t))?.state === 'loaded')) {
    stats.firstFullView = performance.now() - started;
  }
}

// ---------------------------------------------------------------------------------------
// The feature table (EXT_structural_metadata) of a tile, read lazily row by row

const NUMBER_ARRAYS = {
  INT64: BigInt64Array,
  UINT64: BigUint64Array,
  UINT32: Uint32Array,
  UINT16: Uint16Array,
  UINT8: Uint8Array,
  FLOAT32: Float32Array,
  FLOAT64: Float64Array,
};
const COMPONENTS = { SCALAR: 1, VEC2: 2, VEC3: 3, VEC4: 4 };

/** A column of numbers (a scalar or a vector a row), as strings; null where it holds noData. */
function numberColumn(values, declared) {
  const Numbers = NUMBER_ARRAYS[declared.componentType ?? 'INT64'];
  const width = COMPONENTS[declared.type ?? 'SCALAR'];
  if (!Numbers || !width) return () => null;
  const numbers = new Numbers(values, 0, Math.floor(values.byteLength / Numbers.BYTES_PER_ELEMENT));
  const noData = declared.noData === undefined ? null : String(declared.noData);
  return (i) => {
    const row = Array.from(numbers.subarray(i * width, (i + 1) * width), String).join(',');
    return row === noData ? null : row;
  };
}

async function propertyTable(parser) {
  const metadata = parser.json.extensions?.EXT_structural_metadata;
  const table = metadata?.propertyTables?.[0];
  if (!table) return null;
  const views = {};
  const view = async (index) => {
    if (!(index in views)) views[index] = await parser.getDependency('bufferView', index);
    return views[index];
  };
  const columns = {};
  const schema = metadata.schema ?? {};
  const classProperties = schema.classes?.[table.class]?.properties ?? {};
  for (const [name, property] of Object.entries(table.properties)) {
    const values = await view(property.values);
    const enumType = classProperties[name]?.enumType;
    if (property.stringOffsets !== undefined) {
      const raw = await view(property.stringOffsets);
      const offsets =
        property.stringOffsetType === 'UINT16' ? new Uint16Array(raw) : new Uint32Array(raw);
      const bytes = new Uint8Array(values);
      const decoder = new TextDecoder();
      columns[name] = (i) => decoder.decode(bytes.subarray(offsets[i], offsets[i + 1]));
    } else if (enumType !== undefined) {
      const names = new Map((schema.enums?.[enumType]?.values ?? []).map((v) => [v.value, v.name]));
      const bytes = new Uint8Array(values);
      const noData = classProperties[name]?.noData;
      columns[name] = (i) => {
        const found = names.get(bytes[i]) ?? '';
        return found === noData ? null : found;
      };
    } else {
      columns[name] = numberColumn(values, classProperties[name] ?? {});
    }
  }
  return {
    count: table.count,
    /** The rows of an OSM id. */
    rowsOf(osmId) {
      const rows = new Set();
      for (let i = 0; i < table.count; i++) if (columns.osm_id(i) === String(osmId)) rows.add(i);
      return rows;
    },
    row(i) {
      if (!(i >= 0 && i < table.count)) return null;
      const row = {};
      for (const [name, read] of Object.entries(columns)) row[name] = read(i);
      return row;
    },
  };
}

// ---------------------------------------------------------------------------------------
// Picking

const raycaster = new THREE.Raycaster();
const pointer = new THREE.Vector2();
let pressedAt = null;

renderer.domElement.addEventListener('pointerdown', (e) => { pressedAt = [e.clientX, e.clientY]; });
renderer.domElement.addEventListener('pointerup', (e) => {
  if (!pressedAt || Math.hypot(e.clientX - pressedAt[0], e.clientY - pressedAt[1]) > 5) return;
  pick(e.clientX, e.clientY);
});

function pick(clientX, clientY) {
  const rect = renderer.domElement.getBoundingClientRect();
  pointer.set(((clientX - rect.left) / rect.width) * 2 - 1, -((clientY - rect.top) / rect.height) * 2 + 1);
  raycaster.setFromCamera(pointer, camera);
  const groups = [...tiles.values()].filter((t) => t.group?.visible).map((t) => t.group);
  for (const hit of raycaster.intersectObjects(groups, true)) {
    if (!hit.object.visible || hit.object.isInstancedMesh || !hit.face) continue;
    const ids = hit.object.geometry.getAttribute('_feature_id_0');
    let group = hit.object;
    while (group && !group.userData.tile) group = group.parent;
    const table = group?.userData.tile.table;
    if (!ids || !table) continue;
    const row = table.row(ids.getX(hit.face.a));
    if (row) {
      showFeature(row);
      return row;
    }
  }
  hideFeature();
  return null;
}

const featureBox = document.getElementById('feature');
const featureBody = document.getElementById('feature-body');
document.getElementById('feature-close').addEventListener('click', hideFeature);

function showFeature(row) {
  featureBody.replaceChildren();
  let tags = {};
  try {
    tags = JSON.parse(row.tags || '{}');
  } catch (_) {
    // A broken tag column shows no tags.
  }
  const title = document.createElement('h3');
  title.textContent = tags.name || row.class;
  featureBody.append(title);
  const table = document.createElement('table');
  const line = (key, value) => {
    const tr = table.insertRow();
    tr.insertCell().textContent = key;
    const cell = tr.insertCell();
    if (value instanceof Node) cell.append(value);
    else cell.textContent = value;
  };
  line('class', row.class);
  if (row.osm_type !== 'none') {
    const link = document.createElement('a');
    link.href = `https://www.openstreetmap.org/${row.osm_type}/${row.osm_id}`;
    link.target = '_blank';
    link.rel = 'noopener';
    link.textContent = `${row.osm_type} ${row.osm_id}`;
    link.dataset.osmId = row.osm_id;
    line('OSM', link);
  }
  for (const [key, value] of Object.entries(tags).sort()) line(key, value);
  for (const [key, value] of Object.entries(inferredOf(row)).sort()) line(key, `${value} (inferred)`);
  featureBody.append(table);
  featureBox.hidden = false;
}

/** The values a row's tags leave unsaid that were inferred, as the tags they stand for. */
function inferredOf(row) {
  const inferred = {};
  for (const [name, value] of Object.entries(row)) {
    if (!name.startsWith('inferred_') || value === null || value === '') continue;
    const key = name.slice('inferred_'.length).replace('_', ':');
    if (key.endsWith('colour')) {
      const hex = value.split(',').map((c) => Number(c).toString(16).padStart(2, '0')).join('');
      inferred[key] = `#${hex}`;
    } else {
      inferred[key] = value;
    }
  }
  return inferred;
}

function hideFeature() {
  featureBox.hidden = true;
}

// ---------------------------------------------------------------------------------------
// Layers

const layers = { wireframe: false, 'terrain-only': false, debug: false, shadows: false, inferred: false };
const classes = new Map();
const classBox = document.getElementById('classes');

function classOf(node) {
  if (/crown|trunk|tree/.test(node.name)) return 'trees';
  return node.name.replace(/_\d+$/, '');
}

function registerClasses(group) {
  for (const node of group.children) {
    const name = classOf(node);
    if (!name || classes.has(name)) continue;
    classes.set(name, true);
    const label = document.createElement('label');
    const box = document.createElement('input');
    box.type = 'checkbox';
    box.checked = true;
    box.addEventListener('change', () => {
      invalidate();
      classes.set(name, box.checked);
      for (const t of tiles.values()) if (t.group) applyToggles(t.group);
    });
    label.append(box, ` ${name}`);
    classBox.append(label);
  }
}

function applyToggles(group) {
  for (const node of group.children) {
    const name = classOf(node);
    node.visible = layers['terrain-only'] ? name === 'terrain' : classes.get(name) !== false;
  }
  paintInferred(group);
  group.traverse((o) => {
    const materials = Array.isArray(o.material) ? o.material : o.material ? [o.material] : [];
    for (const m of materials) m.wireframe = layers.wireframe;
    if (o.isMesh) {
      // Everything casts and takes shadows but water, which only takes them.
      o.castShadow = !/water/.test(`${o.name} ${o.parent?.name ?? ''}`);
      o.receiveShadow = true;
    }
  });
}

// Shape (roof or levels) inferred; only colours inferred; everything mapped.
const SHAPE_INFERRED = [1.0, 0.4, 0.05];
const COLOURS_INFERRED = [0.95, 0.85, 0.3];
const MAPPED = [0.1, 0.35, 0.9];

/** For each row of a tile's feature table, the colour that says what of it was inferred. */
function inferredColours(table) {
  if (!table) return () => MAPPED;
  if (!table.inferredColours) {
    table.inferredColours = new Map();
    for (let i = 0; i < table.count; i++) {
      const keys = Object.keys(inferredOf(table.row(i)));
      if (keys.some((k) => !k.endsWith('colour'))) table.inferredColours.set(i, SHAPE_INFERRED);
      else if (keys.length > 0) table.inferredColours.set(i, COLOURS_INFERRED);
    }
  }
  return (row) => table.inferredColours.get(row) ?? MAPPED;
}

/** Paints a tile's buildings by what is mapped and what is inferred while the toggle is on,
 *  and gives them back their own colours when it is off. */
function paintInferred(group) {
  const table = group.userData.tile?.table;
  group.traverse((o) => {
    const colours = o.geometry?.getAttribute?.('color');
    const ids = o.geometry?.getAttribute?.('_feature_id_0');
    if (!o.isMesh || o.isInstancedMesh || !colours || !ids) return;
    if (!o.userData.ownColours) {
      if (!layers.inferred) return;
      o.userData.ownColours = colours.array.slice();
    }
    if (layers.inferred) {
      const colourOf = inferredColours(table);
      for (let i = 0; i < colours.count; i++) {
        const [r, g, b] = colourOf(ids.getX(i));
        colours.setXYZ(i, r, g, b);
      }
    } else {
      colours.array.set(o.userData.ownColours);
    }
    colours.needsUpdate = true;
  });
}

for (const box of document.querySelectorAll('[data-toggle]')) {
  box.addEventListener('change', () => {
    invalidate();
    layers[box.dataset.toggle] = box.checked;
    if (box.dataset.toggle === 'shadows') {
      setShadows(box.checked);
      return;
    }
    for (const t of tiles.values()) {
      if (!t.group) continue;
      applyToggles(t.group);
      if (box.dataset.toggle === 'debug') {
        if (box.checked && t.z === ZOOM) addDebug(t);
        else if (t.debug) {
          scene.remove(t.debug);
          dispose(t.debug);
          t.debug = null;
        }
      }
    }
  });
}

/** The elevation debug view of a tile: bridges, tunnels and ground roads as settled. */
async function addDebug(tile) {
  if (tile.debug) return;
  try {
    const response = await fetch(`debug/tiles/${ZOOM}/${tile.x}/${tile.y}.geojson`);
    if (!response.ok) return;
    const collection = await response.json();
    const colours = { bridge: 0xff8800, tunnel: 0x8844ff, road_profile: 0x00bcd4 };
    const group = new THREE.Group();
    for (const feature of collection.features) {
      const p = feature.properties;
      const coordinates = feature.geometry.coordinates;
      if (feature.geometry.type === 'LineString' && Array.isArray(p.elevations_m)) {
        const points = coordinates.map(([lon, lat], i) => worldFromLonLat(lon, lat, p.elevations_m[i] + 0.5));
        const colour = colours[p.layer] ?? colours[p.kind] ?? 0xffffff;
        group.add(new THREE.Line(new THREE.BufferGeometry().setFromPoints(points),
          new THREE.LineBasicMaterial({ color: colour, depthTest: false })));
      } else if (feature.geometry.type === 'Point' && p.satisfied === false) {
        const [lon, lat] = coordinates;
        const marker = new THREE.Mesh(new THREE.SphereGeometry(2, 8, 6),
          new THREE.MeshBasicMaterial({ color: 0xff0000, depthTest: false }));
        marker.position.copy(worldFromLonLat(lon, lat, (p.elevation_m ?? 0) + 1));
        group.add(marker);
      }
    }
    group.renderOrder = 10;
    tile.debug = group;
    scene.add(group);
    invalidate();
  } catch (error) {
    showError(`debug view of ${tile.x}/${tile.y}: ${error.message || error}`);
  }
}

// ---------------------------------------------------------------------------------------
// The place box: "lat, lon"

document.getElementById('place').addEventListener('submit', (e) => {
  e.preventDefault();
  const text = document.getElementById('place-input').value.trim();
  const match = text.match(/^(-?\d+(?:\.\d+)?)\s*[,\s]\s*(-?\d+(?:\.\d+)?)$/);
  if (!match) {
    showError(`"${text}" is not "lat, lon" (e.g. 43.7396, 7.4255)`);
    return;
  }
  const [lat, lon] = [Number(match[1]), Number(match[2])];
  if (Math.abs(lat) > 85 || Math.abs(lon) > 180) {
    showError(`${lat}, ${lon} is outside the map`);
    return;
  }
  const view = currentView();
  jumpTo({ ...view, lat, lon });
});

// ---------------------------------------------------------------------------------------
// Loop

function resize() {
  camera.aspect = container.clientWidth / container.clientHeight;
  camera.updateProjectionMatrix();
  renderer.setSize(container.clientWidth, container.clientHeight);
  invalidate();
}
window.addEventListener('resize', resize);

let lastSchedule = 0;
controls.addEventListener('end', settleOnGround);
controls.addEventListener('change', () => {
  invalidate();
  writeHash();
  const now = performance.now();
  if (now - lastSchedule > 250) {
    lastSchedule = now;
    scheduleTiles();
  }
});

setView(parseHash() || START);
scheduleTiles();
{
  const box = document.querySelector('[data-toggle="shadows"]');
  layers.shadows = !softwareRendering();
  box.checked = layers.shadows;
  setShadows(layers.shadows);
}
// What the last frame cost: from its start to the next tick of the loop, for a frame's drawing
// holds up the page until it is done. While tiles are coming in, a frame that cost more than
// SLOW_FRAME_MS (software WebGL, a weak device) leaves as long again, up to MAX_FRAME_GAP_MS
// (a page left in the background ticks late), to the rest of the page (reading and parsing
// those tiles) before the next one; on a GPU, or with nothing loading, frames follow each other
// as the display asks.
const SLOW_FRAME_MS = 50;
const MAX_FRAME_GAP_MS = 1000;
let frameStarted = null;
let nextFrameAt = 0;
renderer.setAnimationLoop(() => {
  const now = performance.now();
  if (frameStarted !== null) {
    const cost = now - frameStarted;
    nextFrameAt = cost > SLOW_FRAME_MS ? now + Math.min(cost, MAX_FRAME_GAP_MS) : 0;
    frameStarted = null;
  }
  // The damping moves the camera on for a while after the hand lets go: a 'change' each time.
  controls.update();
  if (!redraw || (now < nextFrameAt && tilesLoading())) return;
  redraw = false;
  frameStarted = now;
  followSun(controls.target);
  renderer.render(scene, camera);
  stats.frames++;
});

/** Whether a tile is being fetched or parsed. */
function tilesLoading() {
  for (const tile of tiles.values()) if (tile.state === 'loading') return true;
  return false;
}

/** Where a feature of the loaded tiles shows on screen, for tests: its first vertex in view. */
function locate(osmId) {
  for (const tile of tiles.values()) {
    if (!tile.group?.visible || !tile.table) continue;
    const rows = tile.table.rowsOf(osmId);
    if (rows.size === 0) continue;
    let found = null;
    let tries = 0;
    tile.group.traverse((o) => {
      if (found || !o.isMesh || o.isInstancedMesh || !o.visible) return;
      const ids = o.geometry.getAttribute('_feature_id_0');
      const index = o.geometry.index;
      if (!ids || !index) return;
      for (let i = 0; i < index.count && tries < 200; i += 3) {
        if (!rows.has(ids.getX(index.getX(i)))) continue;
        tries++;
        // The centre of the triangle, on screen.
        const centre = new THREE.Vector3();
        for (let k = 0; k < 3; k++) {
          centre.add(new THREE.Vector3().fromBufferAttribute(o.geometry.attributes.position, index.getX(i + k)));
        }
        centre.divideScalar(3).applyMatrix4(o.matrixWorld);
        const ndc = centre.clone().project(camera);
        if (Math.abs(ndc.x) > 0.9 || Math.abs(ndc.y) > 0.9 || ndc.z > 1) continue;
        // Only where nothing else is in front of it.
        raycaster.setFromCamera(new THREE.Vector2(ndc.x, ndc.y), camera);
        const hit = raycaster.intersectObject(tile.group, true).find((h) => h.object.visible);
        if (!hit || hit.object !== o || ids.getX(hit.face.a) !== ids.getX(index.getX(i))) continue;
        const rect = renderer.domElement.getBoundingClientRect();
        const x = rect.left + ((ndc.x + 1) / 2) * rect.width;
        const y = rect.top + ((1 - ndc.y) / 2) * rect.height;
        // Not where the panel or the search box covers the map: a click there is theirs.
        if (document.elementFromPoint(x, y) !== renderer.domElement) continue;
        found = { x, y };
        return;
      }
    });
    if (found) return found;
  }
  return null;
}

window.terrastitchViewer = {
  stats, locate, pick, currentView, setView: jumpTo, tiles, invalidate,
};
