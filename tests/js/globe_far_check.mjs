// Drives the globe page from far and near above the data, cold then warm, and prints what it saw
// as one JSON object: per view, the time until the tileset said every tile it needs was loaded,
// the zooms of the content tiles drawn, and the fraction of the lower half of the view the
// content covers.
// Usage: node globe_far_check.mjs BASE_URL OUT_DIR VIEW…
//   VIEW  `lat,lon,height,pitch`: the globe page's hash, a point looked at from `height` metres
//         up at `pitch` degrees (from the south; -90 straight down)
import {
  addPixelReader, animationFrames, globeCoverage, launch, watch,
} from './browser.mjs';
import { join } from 'node:path';

const [base, outDir, ...views] = process.argv.slice(2);
const result = { consoleErrors: [], pageErrors: [], failedRequests: [], views: [] };

const browser = await launch();
try {
  for (const pass of ['cold', 'warm']) {
    for (const view of views) {
      const height = Number(view.split(',')[2]);
      const page = await browser.newPage({ viewport: { width: 1024, height: 768 } });
      watch(page, result);
      page.on('response', (response) => {
        if (response.status() >= 400) {
          result.failedRequests.push(`${response.url()}: ${response.status()}`);
        }
      });
      await addPixelReader(page);
      const started = Date.now();
      await page.goto(`${base}globe.html#${view}`, { waitUntil: 'load' });
      await page.waitForFunction(() => {
        const globe = window.terrastitchGlobe;
        return globe?.tileset?.tilesLoaded
          && globe.viewer.scene.globe.tilesLoaded
          && globe.stats.loaded.some((u) => u.includes('.glb'));
      }, null, { timeout: 300000, polling: 250 });
      const settledMs = Date.now() - started;
      await animationFrames(page);
      const name = `globe-${pass}-${height}.png`;
      // A frame of the software-rendered globe can take long on a busy machine.
      await page.screenshot({ path: join(outDir, name), timeout: 120000 });
      const stats = await page.evaluate(() => ({ ...window.terrastitchGlobe.stats }));
      // The zooms of the content drawn now: the tiles selected in the last frame.
      const drawn = await page.evaluate(() => {
        const { tileset } = window.terrastitchGlobe;
        const zooms = {};
        for (const tile of tileset._selectedTiles ?? []) {
          const match = /(\d+)\/\d+\/\d+\.glb/.exec(tile.content?.url ?? '');
          if (match) zooms[match[1]] = (zooms[match[1]] ?? 0) + 1;
        }
        return zooms;
      });
      result.views.push({
        pass,
        view,
        height,
        settledMs,
        terrain: stats.terrain,
        drawnZooms: drawn,
        pixels: await globeCoverage(page),
        screenshot: name,
      });
      await page.close();
    }
  }
} catch (error) {
  result.error = String(error.stack ?? error);
} finally {
  await browser.close();
}
console.log(JSON.stringify(result));
