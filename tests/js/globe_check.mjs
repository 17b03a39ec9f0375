// Drives the globe page (CesiumJS over /tileset.json) in headless Chromium and prints what it
// saw as one JSON object.
// Usage: node globe_check.mjs BASE_URL OUT_DIR LAT LON
//   BASE_URL  the server, e.g. http://127.0.0.1:8080/
//   OUT_DIR   where the screenshots go
//   LAT LON   a building's centre: the camera looks straight down on it and picks what is there
import {
  addPixelReader, animationFrames, globeCoverage, launch, watch,
} from './browser.mjs';
import { join } from 'node:path';

const [base, outDir, lat, lon] = process.argv.slice(2);
const result = { consoleErrors: [], pageErrors: [], failedRequests: [], steps: {} };

const browser = await launch();
try {
  const page = await browser.newPage({ viewport: { width: 1024, height: 768 } });
  watch(page, result);
  await addPixelReader(page);
  const requested = [];
  page.on('request', (request) => requested.push(request.url().replace(base, '/')));

  const loadStarted = Date.now();
  await page.goto(`${base}globe.html`, { waitUntil: 'load' });
  // Settled: the tileset says every tile the view needs is loaded, and content has come.
  await page.waitForFunction(() => {
    const globe = window.terrastitchGlobe;
    return globe?.tileset?.tilesLoaded
      && globe.stats.loaded.filter((u) => u.includes('.glb')).length >= 4;
  }, null, { timeout: 300000, polling: 250 });
  result.steps.firstAllLoadedMs = Date.now() - loadStarted;
  await animationFrames(page);
  await page.screenshot({ path: join(outDir, 'globe-start.png'), timeout: 120000 });
  result.start = await page.evaluate(() => ({ ...window.terrastitchGlobe.stats }));
  result.pixels = await globeCoverage(page);

  // Straight down on the building: the feature at the centre must be it.
  await page.evaluate(([la, lo]) => window.terrastitchGlobe.lookAt(la, lo, 400, -90),
    [Number(lat), Number(lon)]);
  await animationFrames(page);
  await page.waitForFunction(() => window.terrastitchGlobe.tileset.tilesLoaded,
    null, { timeout: 300000, polling: 250 });
  await animationFrames(page);
  result.picked = await page.evaluate(() => window.terrastitchGlobe.pickCentre());
  result.panel = await page.evaluate(() => {
    const panel = document.getElementById('feature');
    const id = panel.querySelector('.osm-id');
    return { visible: !panel.hidden, osmId: id?.dataset.osmId ?? null };
  });
  await page.screenshot({ path: join(outDir, 'globe-picked.png'), timeout: 120000 });
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
