// Opens the viewer and the globe with no place in their URLs and prints, as one JSON object,
// where each looked and what it asked for.
// Usage: node open_check.mjs BASE_URL OUT_DIR
//   BASE_URL  the server, e.g. http://127.0.0.1:8080/
//   OUT_DIR   where the screenshots go
import { animationFrames, launch, watch } from './browser.mjs';
import { join } from 'node:path';

const [base, outDir] = process.argv.slice(2);
const result = { consoleErrors: [], pageErrors: [], failedRequests: [], steps: {} };

const browser = await launch();
try {
  const page = await browser.newPage({ viewport: { width: 480, height: 360 } });
  watch(page, result);
  const answers = [];
  page.on('response', (response) => answers.push([response.status(), response.url().replace(base, '/')]));

  await page.goto(base, { waitUntil: 'load' });
  // `terrastitchViewer` appears once the viewer has read tiles.json: wait for it, and then for
  // its first full view.
  await page.waitForFunction(() => (window.terrastitchViewer?.stats.firstFullView ?? null) !== null,
    null, { timeout: 240000, polling: 200 });
  result.viewer = await page.evaluate(() => ({
    loaded: [...window.terrastitchViewer.stats.loaded],
    failed: [...window.terrastitchViewer.stats.failed],
  }));
  // The viewer keeps its place in the URL (written a moment after the view settles).
  await page.waitForFunction(() => location.hash.length > 1, null, { timeout: 240000 });
  await animationFrames(page);
  result.viewer.hash = await page.evaluate(() => location.hash);
  await page.screenshot({ path: join(outDir, 'viewer-open.png') });

  await page.goto(`${base}globe.html`, { waitUntil: 'load' });
  await page.waitForFunction(() => {
    const globe = window.terrastitchGlobe;
    return globe?.tileset?.tilesLoaded && globe.stats.loaded.some((u) => u.includes('.glb'));
  }, null, { timeout: 240000, polling: 250 });
  result.globe = await page.evaluate(() => {
    const { viewer, stats } = window.terrastitchGlobe;
    // Where the view's centre meets the ellipsoid.
    const canvas = viewer.scene.canvas;
    const centre = new Cesium.Cartesian2(canvas.clientWidth / 2, canvas.clientHeight / 2);
    const point = viewer.camera.pickEllipsoid(centre);
    const at = point && Cesium.Cartographic.fromCartesian(point);
    return {
      loaded: [...stats.loaded],
      failed: [...stats.failed],
      looksAt: at && [Cesium.Math.toDegrees(at.longitude), Cesium.Math.toDegrees(at.latitude)],
    };
  });
  await page.screenshot({ path: join(outDir, 'globe-open.png'), timeout: 120000 });
  result.answers = answers;
} catch (error) {
  result.error = String(error.stack ?? error);
} finally {
  await browser.close();
}
console.log(JSON.stringify(result));
