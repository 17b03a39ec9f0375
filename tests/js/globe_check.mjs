// Drives the globe page (CesiumJS over /tileset.json, the server's terrain under it) in headless
// Chromium through one session and prints what it saw as one JSON object: its start view, each
// view asked for, and a pick straight down on a building.
// Usage: node globe_check.mjs BASE_URL OUT_DIR LAT LON VIEW…
//   BASE_URL  the server, e.g. http://127.0.0.1:8080/
//   OUT_DIR   where the screenshots go
//   LAT LON   a building's centre: the camera looks straight down on it and picks what is there
//   VIEW      `lat,lon,height,pitch`: a point looked at from `height` metres up at `pitch`
//             degrees (from the south; -90 straight down)
import {
  addPixelReader, animationFrames, globeCoverage, launch, watch,
} from './browser.mjs';
import { join } from 'node:path';

const [base, outDir, lat, lon, ...views] = process.argv.slice(2);
const result = {
  consoleErrors: [], pageErrors: [], failedRequests: [], steps: {}, views: [],
};

// Every wait is on the page's own signals; the bound means "it hung", never "it was slow".
const HUNG_MS = 300000;

const browser = await launch();
try {
  const page = await browser.newPage({ viewport: { width: 480, height: 360 } });
  page.setDefaultTimeout(HUNG_MS);
  watch(page, result);
  page.on('response', (response) => {
    if (response.status() >= 400) {
      result.failedRequests.push(`${response.url()}: ${response.status()}`);
    }
  });
  await addPixelReader(page);
  const requested = [];
  page.on('request', (request) => requested.push(request.url().replace(base, '/')));
  // Settled: the frames drawn since the camera moved asked for what the view needs, and the
  // tileset and the globe say all of it is loaded.
  const settled = async () => {
    await animationFrames(page);
    await page.waitForFunction(() => {
      const globe = window.terrastitchGlobe;
      return globe.tileset.tilesLoaded && globe.viewer.scene.globe.tilesLoaded;
    }, null, { timeout: HUNG_MS, polling: 250 });
    await animationFrames(page);
  };

  const loadStarted = Date.now();
  await page.goto(`${base}globe.html`, { waitUntil: 'load' });
  await page.waitForFunction(() => {
    const globe = window.terrastitchGlobe;
    return globe?.tileset?.tilesLoaded
      && globe.stats.loaded.filter((u) => u.includes('.glb')).length >= 4;
  }, null, { timeout: HUNG_MS, polling: 250 });
  result.steps.firstAllLoadedMs = Date.now() - loadStarted;
  await animationFrames(page);
  await page.screenshot({ path: join(outDir, 'globe-start.png') });
  result.start = await page.evaluate(() => ({ ...window.terrastitchGlobe.stats }));
  result.pixels = await globeCoverage(page);

  for (const view of views) {
    const [la, lo, height, pitch] = view.split(',').map(Number);
    const started = Date.now();
    await page.evaluate((v) => window.terrastitchGlobe.lookAt(...v), [la, lo, height, pitch]);
    await settled();
    const settledMs = Date.now() - started;
    const name = `globe-${height}.png`;
    await page.screenshot({ path: join(outDir, name) });
    // The zooms of the content drawn now: the tiles selected in the last frame.
    const drawnZooms = await page.evaluate(() => {
      const { tileset } = window.terrastitchGlobe;
      const zooms = {};
      for (const tile of tileset._selectedTiles ?? []) {
        const match = /(\d+)\/\d+\/\d+\.glb/.exec(tile.content?.url ?? '');
        if (match) zooms[match[1]] = (zooms[match[1]] ?? 0) + 1;
      }
      return zooms;
    });
    result.views.push({
      view,
      height,
      settledMs,
      terrain: await page.evaluate(() => window.terrastitchGlobe.stats.terrain),
      drawnZooms,
      pixels: await globeCoverage(page),
      screenshot: name,
    });
  }

  // Straight down on the building: the feature at the centre must be it.
  await page.evaluate(([la, lo]) => window.terrastitchGlobe.lookAt(la, lo, 400, -90),
    [Number(lat), Number(lon)]);
  await settled();
  result.picked = await page.evaluate(() => window.terrastitchGlobe.pickCentre());
  result.panel = await page.evaluate(() => {
    const panel = document.getElementById('feature');
    const id = panel.querySelector('.osm-id');
    return { visible: !panel.hidden, osmId: id?.dataset.osmId ?? null };
  });
  await page.screenshot({ path: join(outDir, 'globe-picked.png') });
  result.end = await page.evaluate(() => ({ ...window.terrastitchGlobe.stats }));
  result.requests = {
    tilesets: requested.filter((u) => /\/tileset\.json|\/3dtiles\/.*\.json/.test(u)).length,
    content: requested.filter((u) => u.includes('.glb')),
  };
} catch (error) {
  result.error = String(error.stack ?? error);
} finally {
  await browser.close();
}
console.log(JSON.stringify(result));
