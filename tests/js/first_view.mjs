// Opens the viewer in headless Chromium and prints, as one JSON object, how long its start view
// took to show completely (the nine zoom-14 tiles around the point looked at), as the page
// measures it and from the request of the page, with the tiles it asked for by then.
// Usage: node first_view.mjs URL   (the viewer's URL, with its start view after `#`)
import { launch, watch } from './browser.mjs';

const [url] = process.argv.slice(2);
const result = { consoleErrors: [], pageErrors: [], failedRequests: [] };
// A bound that means "it hung", not "it was slow".
const HUNG_MS = 240000;

const browser = await launch();
try {
  const page = await browser.newPage({ viewport: { width: 480, height: 360 } });
  watch(page, result);
  const started = Date.now();
  await page.goto(url, { waitUntil: 'load' });
  await page.waitForFunction(() => (window.terrastitchViewer?.stats.firstFullView ?? null) !== null,
    null, { timeout: HUNG_MS, polling: 50 });
  result.firstFullViewMs = Date.now() - started;
  const stats = await page.evaluate(() => {
    const s = window.terrastitchViewer.stats;
    return { inPageMs: s.firstFullView, requested: [...s.requested], loaded: [...s.loaded] };
  });
  Object.assign(result, stats);
} catch (error) {
  result.error = String(error.stack || error);
} finally {
  await browser.close();
}
console.log(JSON.stringify(result));
