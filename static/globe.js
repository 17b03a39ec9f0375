// The served tiles on a CesiumJS globe, loaded as a 3D Tiles 1.1 tileset (`/tileset.json`):
// content in east-north-up frames placed by each tile's transform, features picked from the
// tile's EXT_structural_metadata table. The globe's surface is the server's own quantized-mesh
// terrain (`/layer.json`), made from the same ground as the content, so the content sits on it
// (lifted by `CONTENT_LIFT_M`, a drawing bias only: where the two surfaces are the same
// triangles, the content's are drawn in front). Parents of the tileset carry coarse content, so
// a view from far away shows the data before the zoom-14 tiles open. No imagery is asked for.
//
// Query: ?compress=none for uncompressed content (meshopt by default); ?terrain=none for the
// bare WGS 84 ellipsoid instead of the server's terrain; the URL hash `#lat,lon,height` sets where
// the camera looks from (else the centre of the server's data), `#lat,lon,height,pitch` also how
// steeply (degrees, -90 straight down; -45 by default).
/* global Cesium */

const params = new URLSearchParams(window.location.search);
const compress = params.get('compress') ?? 'meshopt';
const ownTerrain = params.get('terrain') !== 'none';
/** How far the content is drawn above the terrain it shares its ground with, metres. */
const CONTENT_LIFT_M = 0.5;
const status = document.getElementById('status');

const stats = {
  terrain: null,
  loaded: [],
  failed: [],
  allLoaded: false,
  firstAllLoaded: null,
};
const started = performance.now();

const viewer = new Cesium.Viewer('globe', {
  baseLayer: false,
  baseLayerPicker: false,
  geocoder: false,
  timeline: false,
  animation: false,
  homeButton: false,
  sceneModePicker: false,
  navigationHelpButton: false,
  fullscreenButton: false,
  infoBox: false,
  selectionIndicator: false,
  terrainProvider: new Cesium.EllipsoidTerrainProvider(),
  // A frame is drawn only when the scene changes (the camera, a tile loaded): an idle globe
  // costs nothing. Nothing here changes with the clock.
  requestRenderMode: true,
  maximumRenderTimeChange: Infinity,
});
if (ownTerrain) {
  try {
    viewer.terrainProvider = await Cesium.CesiumTerrainProvider.fromUrl('.', {
      requestVertexNormals: true,
    });
    stats.terrain = 'server';
  } catch (error) {
    // An archive of glb tiles has no terrain: the ellipsoid stays.
    stats.terrain = `ellipsoid (${error.message ?? error})`;
  }
} else {
  stats.terrain = 'ellipsoid';
}
// No imagery: the server's terrain reaches over every SRTM file it has (the layer's bounds),
// past the content's box, and shows there in the colour of bare ground in the content, not as
// a dark void.
viewer.scene.globe.baseColor = Cesium.Color.fromCssColorString('#adbf95');
viewer.scene.globe.depthTestAgainstTerrain = false;

function showError(message) {
  status.textContent = message;
  status.className = 'error';
}

function viewFromHash() {
  const parts = window.location.hash.slice(1).split(',').map(Number);
  if (parts.length >= 2 && parts.every(Number.isFinite)) {
    return { lat: parts[0], lon: parts[1], height: parts[2] ?? 1500, pitch: parts[3] ?? -45 };
  }
  return null;
}

/** Looks at a point from the south, `height` metres up. */
function lookAt(lat, lon, height, pitchDegrees = -45) {
  const pitch = Cesium.Math.toRadians(pitchDegrees);
  const back = pitchDegrees <= -89 ? 0 : height / Math.tan(-pitch);
  const metresPerDegree = 111320;
  viewer.camera.setView({
    destination: Cesium.Cartesian3.fromDegrees(lon, lat - back / metresPerDegree, height),
    orientation: { heading: 0, pitch, roll: 0 },
  });
}

function escapeHtml(text) {
  return String(text).replace(/[&<>"']/g, (c) => `&#${c.charCodeAt(0)};`);
}

function showFeature(feature) {
  const panel = document.getElementById('feature');
  const type = String(feature.getProperty('osm_type') ?? '');
  const id = String(feature.getProperty('osm_id') ?? '');
  let tags = {};
  try {
    tags = JSON.parse(feature.getProperty('tags') ?? '{}');
  } catch (error) {
    tags = {};
  }
  const rows = Object.entries(tags)
    .map(([k, v]) => `<tr><td>${escapeHtml(k)}</td><td>${escapeHtml(v)}</td></tr>`)
    .join('');
  const link = type === 'none'
    ? ''
    : `<a href="https://www.openstreetmap.org/${escapeHtml(type)}/${escapeHtml(id)}" target="_blank" rel="noopener">openstreetmap.org</a>`;
  document.getElementById('feature-body').innerHTML = `
    <div><strong>${escapeHtml(feature.getProperty('class') ?? '')}</strong>
      ${escapeHtml(tags.name ?? '')}</div>
    <div class="osm-id" data-osm-type="${escapeHtml(type)}" data-osm-id="${escapeHtml(id)}">${escapeHtml(type)} ${escapeHtml(id)} ${link}</div>
    <table>${rows}</table>`;
  panel.hidden = false;
}

document.getElementById('feature-close').addEventListener('click', () => {
  document.getElementById('feature').hidden = true;
});

/** The feature drawn at a canvas position, if any. */
function pick(x, y) {
  const picked = viewer.scene.pick(new Cesium.Cartesian2(x, y));
  return picked instanceof Cesium.Cesium3DTileFeature ? picked : null;
}

viewer.screenSpaceEventHandler.setInputAction((click) => {
  const feature = pick(click.position.x, click.position.y);
  if (feature) showFeature(feature);
}, Cesium.ScreenSpaceEventType.LEFT_CLICK);

let tileset = null;
try {
  tileset = await Cesium.Cesium3DTileset.fromUrl(`tileset.json?compress=${encodeURIComponent(compress)}`);
  viewer.scene.primitives.add(tileset);
  if (stats.terrain === 'server') {
    // Up at the tileset's centre, by the lift.
    const centre = tileset.boundingSphere.center;
    const up = Cesium.Ellipsoid.WGS84.geodeticSurfaceNormal(centre, new Cesium.Cartesian3());
    tileset.modelMatrix = Cesium.Matrix4.fromTranslation(
      Cesium.Cartesian3.multiplyByScalar(up, CONTENT_LIFT_M, up),
    );
  }
  viewer.scene.requestRender();
  tileset.tileLoad.addEventListener((tile) => {
    stats.loaded.push(tile.content.url.replace(/^.*3dtiles\//, ''));
  });
  tileset.tileFailed.addEventListener((error) => {
    stats.failed.push(`${error.url}: ${error.message}`);
    showError(`A tile failed: ${error.url}: ${error.message}`);
  });
  tileset.loadProgress.addEventListener((pending, processing) => {
    if (!status.classList.contains('error')) {
      status.textContent = pending + processing > 0 ? `loading ${pending + processing} tiles…` : '';
    }
  });
  tileset.allTilesLoaded.addEventListener(() => {
    stats.allLoaded = true;
    if (stats.firstAllLoaded === null) stats.firstAllLoaded = performance.now() - started;
  });
} catch (error) {
  showError(`The tileset could not be loaded: ${error.message ?? error}`);
}

/** The centre of the server's data (`/tiles.json`), or null when it does not say. */
async function dataCentre() {
  try {
    const [lon, lat] = (await (await fetch('tiles.json')).json()).center ?? [];
    if (Number.isFinite(lon) && Number.isFinite(lat)) return { lat, lon, height: 1500 };
  } catch (error) {
    // No description: the page's own start.
  }
  return null;
}

// Where the URL says, else over the server's data, else Monte-Carlo (the bundled sample).
const start = viewFromHash() ?? (await dataCentre()) ?? { lat: 43.7384, lon: 7.4246, height: 1500 };
lookAt(start.lat, start.lon, start.height, start.pitch ?? -45);

/** The direction of a light from the south-west, 50° up, over a place (what travels from the
 *  light to the scene, in the world's frame). */
function lightOver(lat, lon) {
  const frame = Cesium.Transforms.eastNorthUpToFixedFrame(Cesium.Cartesian3.fromDegrees(lon, lat));
  const up = Math.sin(Cesium.Math.toRadians(50));
  const across = Math.cos(Cesium.Math.toRadians(50)) / Math.SQRT2;
  const towards = new Cesium.Cartesian3(across, across, -up);
  const world = Cesium.Matrix4.multiplyByPointAsVector(frame, towards, new Cesium.Cartesian3());
  return Cesium.Cartesian3.normalize(world, world);
}
// One fixed light rather than the sun of the clock's hour: the ground beyond the content is
// shaded by its relief (the globe lit as the content is), and nothing goes dark at night.
viewer.scene.light = new Cesium.DirectionalLight({
  direction: lightOver(start.lat, start.lon),
  intensity: 2.0, // as bright as the default sun
});
viewer.scene.globe.enableLighting = true;

window.terrastitchGlobe = {
  viewer,
  tileset,
  stats,
  lookAt,
  /** The OSM type and id of the feature at the canvas's centre, or null. */
  pickCentre() {
    const canvas = viewer.scene.canvas;
    const feature = pick(canvas.clientWidth / 2, canvas.clientHeight / 2);
    if (!feature) return null;
    showFeature(feature);
    return {
      osmType: String(feature.getProperty('osm_type')),
      osmId: String(feature.getProperty('osm_id')),
      class: String(feature.getProperty('class')),
    };
  },
};
