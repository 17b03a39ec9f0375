// Drives the viewer in headless Chromium and prints what it saw as one JSON object.
// Usage: node viewer_check.mjs BASE_URL OUT_DIR OSM_ID
//   BASE_URL  the server, e.g. http://127.0.0.1:8080/
//   OUT_DIR   where the screenshots go
//   OSM_ID    a building near the start view to click on
import { addPixelReader, launch, watch } from './browser.mjs';
import { writeFileSync } from 'node:fs';
import { join } from 'node:path';

const [base, outDir, osmId] = process.argv.slice(2);
const result = {
  consoleErrors: [],
  pageErrors: [],
  failedRequests: [],
  steps: {},
};

// Every wait is on the page's own signals (its first full view, the frames it has drawn, the
// tiles it has loaded); the bound on each means "it hung", never "it was slow": software WebGL
// on a busy machine can take most of a minute for a frame.
const HUNG_MS = 240000;

const browser = await launch();
try {
  const page = await browser.newPage({ viewport: { width: 480, height: 360 } });
  page.setDefaultTimeout(HUNG_MS);
  watch(page, result);
  await addPixelReader(page);
  const stats = () => page.evaluate(() => {
    const s = window.terrastitchViewer.stats;
    return { requested: [...s.requested], loaded: [...s.loaded], failed: [...s.failed],
      frames: s.frames, firstFullView: s.firstFullView };
  });
  // Waits until the page has drawn `count` frames more than it has now. It draws only what
  // changed: each look asks it for a frame.
  const frames = async (count) => {
    const now = (await stats()).frames;
    await page.waitForFunction((until) => {
      const viewer = window.terrastitchViewer;
      if (viewer.stats.frames < until) viewer.invalidate();
      return viewer.stats.frames >= until;
    }, now + count, { timeout: HUNG_MS, polling: 100 });
  };

  const loadStarted = Date.now();
  await page.goto(base, { waitUntil: 'load' });
  // The viewer sets `terrastitchViewer` once it has read tiles.json: until then there is no
  // first view to wait for (and `undefined !== null` would end the wait at once).
  await page.waitForFunction(() => (window.terrastitchViewer?.stats.firstFullView ?? null) !== null,
    null, { timeout: HUNG_MS, polling: 200 });
  result.steps.firstFullViewMs = Date.now() - loadStarted;
  result.steps.firstFullViewInPageMs = (await stats()).firstFullView;
  result.start = await stats();
  result.glRenderer = await page.evaluate(() => {
    const gl = document.createElement('canvas').getContext('webgl2');
    const info = gl && gl.getExtension('WEBGL_debug_renderer_info');
    return info ? gl.getParameter(info.UNMASKED_RENDERER_WEBGL) : null;
  });
  // A few frames more, so what loaded is drawn.
  await frames(3);
  await page.screenshot({ path: join(outDir, 'viewer-start.png') });

  // Is anything drawn? Pixels of the canvas, read through a 2D canvas.
  result.pixels = await page.evaluate(() => {
    const data = window.canvasPixels(document.querySelector('#map canvas'));
    const colours = new Set();
    let dark = 0;
    for (let i = 0; i < data.length; i += 4) {
      colours.add((data[i] >> 3) << 10 | (data[i + 1] >> 3) << 5 | (data[i + 2] >> 3));
      if (data[i] + data[i + 1] + data[i + 2] < 30) dark++;
    }
    return { distinctColours: colours.size, darkFraction: dark / (data.length / 4) };
  });

  // Sun shadows: off on software WebGL; turned on, they darken the ground behind buildings.
  const brightness = () => page.evaluate(() => {
    const data = window.canvasPixels(document.querySelector('#map canvas'));
    let sum = 0;
    for (let i = 0; i < data.length; i += 4) sum += data[i] + data[i + 1] + data[i + 2];
    return sum / (data.length / 4) / 765;
  });
  result.shadows = { defaultOn: await page.isChecked('[data-toggle="shadows"]') };
  result.shadows.brightnessWithout = await brightness();
  await page.click('[data-toggle="shadows"]');
  await frames(3);
  result.shadows.brightnessWith = await brightness();
  await page.screenshot({ path: join(outDir, 'viewer-shadows.png') });
  await page.click('[data-toggle="shadows"]');
  await frames(3);

  // Mapped / inferred: on, buildings whose roof or levels were inferred turn orange; off, they
  // take their own colours back.
  const orange = () => page.evaluate(() => {
    const data = window.canvasPixels(document.querySelector('#map canvas'));
    let count = 0;
    for (let i = 0; i < data.length; i += 4) {
      if (data[i] > 150 && data[i + 1] > 40 && data[i + 1] < 130 && data[i + 2] < 60) count++;
    }
    return count / (data.length / 4);
  });
  result.inferred = { before: await orange() };
  await page.click('[data-toggle="inferred"]');
  await frames(3);
  result.inferred.on = await orange();
  await page.screenshot({ path: join(outDir, 'viewer-inferred.png') });
  await page.click('[data-toggle="inferred"]');
  await frames(3);
  result.inferred.off = await orange();

  // Click on a known building and read the panel.
  const spot = await page.evaluate((id) => window.terrastitchViewer.locate(id), osmId);
  result.click = { spot };
  if (spot) {
    await page.mouse.click(spot.x, spot.y);
    await page.waitForFunction(() => !document.getElementById('feature').hidden, null,
      { timeout: HUNG_MS, polling: 100 }).catch(() => {});
    result.click.panelVisible = await page.evaluate(() => !document.getElementById('feature').hidden);
    result.click.osmIds = await page.evaluate(() => [...document.querySelectorAll('#feature [data-osm-id]')]
      .map((a) => a.dataset.osmId));
    result.click.text = await page.evaluate(() => document.getElementById('feature').innerText);
    await page.screenshot({ path: join(outDir, 'viewer-click.png') });
  }

  // Frame rate while the camera turns.
  const framesBefore = (await stats()).frames;
  const turnStarted = Date.now();
  await page.evaluate(() => new Promise((resolve) => {
    const v = window.terrastitchViewer.currentView();
    let step = 0;
    const turn = () => {
      window.terrastitchViewer.setView({ ...v, heading: v.heading + step * 6 });
      step++;
      if (step < 20) requestAnimationFrame(turn);
      else resolve();
    };
    turn();
  }));
  result.steps.framesPerSecond = ((await stats()).frames - framesBefore) / ((Date.now() - turnStarted) / 1000);

  // Move two kilometres east: tiles not asked for before are asked for and shown.
  const before = new Set((await stats()).requested);
  await page.evaluate(() => {
    const v = window.terrastitchViewer.currentView();
    window.terrastitchViewer.setView({ ...v, lon: v.lon + 0.03 });
  });
  await page.waitForFunction((asked) => {
    const s = window.terrastitchViewer.stats;
    const fresh = s.loaded.filter((t) => !asked.includes(t));
    return fresh.length >= 3;
  }, [...before], { timeout: HUNG_MS, polling: 200 });
  // The moved view reaches the URL (written a moment after the view settles).
  await page.waitForFunction(() => {
    const v = window.terrastitchViewer.currentView();
    const lon = Number(location.hash.replace(/^#/, '').split(',')[1]);
    return Math.abs(lon - v.lon) < 1e-4;
  }, null, { timeout: HUNG_MS, polling: 100 });
  const after = await stats();
  result.moved = {
    newlyRequested: after.requested.filter((t) => !before.has(t)),
    newlyLoaded: after.loaded.filter((t) => !before.has(t)),
    hash: await page.evaluate(() => location.hash),
  };
  await frames(2);
  await page.screenshot({ path: join(outDir, 'viewer-moved.png') });

  // Draw back to 40 km: the far-view tiles stand in, and the view settles with nothing loading.
  await page.evaluate(() => {
    const v = window.terrastitchViewer.currentView();
    window.terrastitchViewer.setView({ ...v, distance: 40000, tilt: 40 });
  });
  const farStarted = Date.now();
  await page.waitForFunction(() => {
    const tiles = [...window.terrastitchViewer.tiles.values()];
    return tiles.some((t) => t.z < 14 && t.group?.visible)
      && !tiles.some((t) => t.state === 'loading' || t.state === 'queued');
  }, null, { timeout: HUNG_MS, polling: 200 });
  await frames(2);
  await page.screenshot({ path: join(outDir, 'viewer-far.png') });
  result.far = await page.evaluate(() => {
    const shown = [...window.terrastitchViewer.tiles.values()].filter((t) => t.group?.visible);
    const zooms = {};
    for (const t of shown) zooms[t.z] = (zooms[t.z] ?? 0) + 1;
    return { shownZooms: zooms };
  });
  result.far.settledMs = Date.now() - farStarted;
  result.far.pixels = await page.evaluate(() => {
    const data = window.canvasPixels(document.querySelector('#map canvas'));
    const colours = new Set();
    for (let i = 0; i < data.length; i += 4) {
      colours.add((data[i] >> 3) << 10 | (data[i + 1] >> 3) << 5 | (data[i + 2] >> 3));
    }
    return { distinctColours: colours.size };
  });
  result.end = await stats();
} catch (error) {
  result.error = String(error.stack || error);
} finally {
  await browser.close();
}
writeFileSync(join(outDir, 'viewer-report.json'), JSON.stringify(result, null, 2));
console.log(JSON.stringify(result));
