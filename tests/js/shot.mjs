// Screenshots of the viewer at given views: node shot.mjs BASE OUT_PREFIX VIEW...
// VIEW is `lat,lon,distance,heading,tilt`.
import { launch } from './browser.mjs';
const [base, prefix, ...views] = process.argv.slice(2);
const browser = await launch();
try {
  const page = await browser.newPage({ viewport: { width: 1000, height: 700 } });
  for (const [i, view] of views.entries()) {
    await page.goto(`${base}/?compress=none#${view}`, { waitUntil: 'load' });
    await page.reload({ waitUntil: 'load' });
    await page.waitForFunction(() => (window.terrastitchViewer?.stats.firstFullView ?? null) !== null,
      null, { timeout: 240000, polling: 200 });
    await page.waitForFunction(() => ![...window.terrastitchViewer.tiles.values()]
      .some((t) => t.state === 'loading' || t.state === 'queued'), null, { timeout: 240000, polling: 200 });
    await page.evaluate(() => window.terrastitchViewer.invalidate());
    await page.waitForTimeout(500);
    await page.screenshot({ path: `${prefix}-${i}.png` });
  }
} finally {
  await browser.close();
}
