// Debian's Chromium, headless with software WebGL, as every browser check here launches it
// (the background-networking flags keep it from reaching for Google's hosts).
import { chromium } from 'playwright-core';

export function launch() {
  return chromium.launch({
    executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
    args: [
      '--headless', '--no-sandbox', '--disable-gpu', '--disable-background-networking',
      '--disable-component-update', '--disable-sync', '--no-first-run', '--use-angle=swiftshader',
      '--enable-unsafe-swiftshader',
    ],
  });
}

/**
 * Records into `result` what went wrong on the page: console errors, uncaught exceptions, a
 * crash, and requests that failed on the network (`consoleErrors`, `pageErrors`,
 * `failedRequests`).
 */
export function watch(page, result) {
  result.consoleErrors ??= [];
  result.pageErrors ??= [];
  result.failedRequests ??= [];
  page.on('console', (message) => {
    if (message.type() === 'error') result.consoleErrors.push(message.text());
  });
  page.on('pageerror', (error) => result.pageErrors.push(String(error)));
  page.on('crash', () => result.pageErrors.push('the page crashed'));
  page.on('requestfailed', (request) => {
    result.failedRequests.push(`${request.url()}: ${request.failure()?.errorText}`);
  });
}

/** Makes `window.canvasPixels(canvas)` on the page: a canvas's pixels at 256×192 (RGBA). */
export async function addPixelReader(page) {
  await page.addInitScript(() => {
    window.canvasPixels = (source) => {
      const canvas = document.createElement('canvas');
      canvas.width = 256;
      canvas.height = 192;
      const context = canvas.getContext('2d');
      context.drawImage(source, 0, 0, canvas.width, canvas.height);
      return context.getImageData(0, 0, canvas.width, canvas.height).data;
    };
  });
}

/**
 * On the globe page: how many distinct colours the view has, and the fraction of the lower half
 * of the view the tileset changes (the same view drawn without it, compared pixel by pixel).
 */
export async function globeCoverage(page) {
  return page.evaluate(() => {
    const { viewer, tileset } = window.terrastitchGlobe;
    // Drawn now and read at once (the page draws only on change, and a drawing buffer is
    // not kept past its frame).
    const read = () => {
      viewer.scene.requestRender();
      viewer.render();
      return window.canvasPixels(viewer.scene.canvas);
    };
    const withTiles = read();
    // The same view without the tileset: what the tiles change is what they draw.
    tileset.show = false;
    const bare = read();
    tileset.show = true;
    viewer.scene.requestRender();
    viewer.render();
    const colours = new Set();
    let changed = 0;
    let lower = 0;
    for (let i = 0; i < withTiles.length; i += 4) {
      colours.add((withTiles[i] >> 3) << 10 | (withTiles[i + 1] >> 3) << 5 | (withTiles[i + 2] >> 3));
      if (i / 4 >= (256 * 192) / 2) {
        lower++;
        const off = Math.abs(withTiles[i] - bare[i]) + Math.abs(withTiles[i + 1] - bare[i + 1])
          + Math.abs(withTiles[i + 2] - bare[i + 2]);
        if (off > 30) changed++;
      }
    }
    return { distinctColours: colours.size, contentFraction: changed / lower };
  });
}

/**
 * Waits for `count` animation frames of the page: whatever it loaded before is drawn by then.
 * A signal of the page, not a clock; a busy machine only makes it come later.
 */
export async function animationFrames(page, count = 3) {
  await page.evaluate((n) => new Promise((done) => {
    const step = (left) => (left === 0 ? done() : requestAnimationFrame(() => step(left - 1)));
    step(n);
  }), count);
}
