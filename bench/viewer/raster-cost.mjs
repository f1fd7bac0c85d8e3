// Raster cost of one canvas frame drawn in full with and without the viewer's pruning of hidden
// tiles and hidden parts of tiles (client-web/src/occlusion.js), in the states view loads pass
// through.
//
//   node bench/viewer/raster-cost.mjs      (needs target/release/vtex and client-web/dist)
//
// 60 seeded view changes (jumps at zooms 1/128 … 2, half-to-one-screen pans, zooms × 2 or ÷ 2)
// over the 100k × 100k chaos mosaic, twice: the first pass warms the server's cache, the second
// (fresh browser) measures. After each frame with tiles hidden whole or in part, the page draws
// that frame again in full three times each way, alternating, each followed by a 1-px
// getImageData, which makes Chromium raster the recorded drawing — the work its canvas flush
// (Canvas2DResourceProviderSharedImage::ProduceCanvasResource) does for a frame — before it
// returns. Reports the median per frame, summarised over the frames.
import { launchBrowser, openViewer, startServer, waitForIdle } from '../../tests/browser/lib.mjs';
const server = await startServer({ extraArgs: ['--cache-mb', '2048'] });
const textures = (await (await fetch(`${server.url}/api/v1/textures`)).json()).textures;
const big = textures.find((t) => t.model === 'chaos-mosaic' && t.width >= 100_000);
let seed = 7;
const rnd = () => ((seed = (seed * 1103515245 + 12345) >>> 0) / 2 ** 32);
const views = [];
let v = { zoom: 0.05, x: 50_000, y: 50_000 };
for (let i = 0; i < 60; i++) {
  const k = i % 3;
  if (k === 0) v = { zoom: 2 ** (-7 + 8 * rnd()), x: 5_000 + 90_000 * rnd(), y: 5_000 + 90_000 * rnd() };
  else if (k === 1) v = { ...v, x: v.x + ((rnd() < 0.5 ? -1 : 1) * (480 + 480 * rnd())) / v.zoom };
  else v = { ...v, zoom: v.zoom * (rnd() < 0.5 ? 2 : 0.5) };
  views.push(v);
}
async function pass(measure) {
  const browser = await launchBrowser();
  const { page } = await openViewer(browser.context, `${server.url}/?texture=${big.id}&zoom=0.01&x=50000&y=50000`);
  await waitForIdle(page);
  if (measure)
    await page.evaluate(() => {
      const { viewer, frames } = window.vtexViewer;
      const drawer = viewer.drawer;
      const draw = drawer.draw;
      window.costs = [];
      let busy = false;
      drawer.draw = (items) => {
        draw(items);
        if (busy) return;
        const item = items.find((i) => i.opacity !== 0);
        if (!item || !item._lastDrawn) return;
        const h0 = frames.hidden;
        const p0 = frames.pixels;
        busy = true;
        const t = { on: [], off: [], hidden: 0, spared: 0, pxOn: 0, pxOff: 0, tiles: item._lastDrawn.length };
        for (let r = 0; r < 3; r++) {
          for (const prune of [false, true]) {
            frames.prune = prune;
            const hb = frames.hidden;
            const sb = frames.hiddenPixels;
            const pb = frames.pixels;
            const s = performance.now();
            draw(items);
            drawer.context.getImageData(0, 0, 1, 1);
            (prune ? t.on : t.off).push(performance.now() - s);
            if (prune) {
              t.hidden = frames.hidden - hb;
              t.spared = frames.hiddenPixels - sb;
              t.pxOn = frames.pixels - pb;
            } else t.pxOff = frames.pixels - pb;
          }
        }
        busy = false;
        if (t.spared > 0) window.costs.push(t);
      };
    });
  for (const view of views) {
    await page.evaluate((v) => window.vtexViewer.setView(v, true), view);
    await waitForIdle(page);
  }
  const costs = measure ? await page.evaluate(() => window.costs) : null;
  await browser.close();
  return costs;
}
await pass(false); // warms the server's cache
const costs = await pass(true);
await server.stop();
const med = (a) => [...a].sort((x, y) => x - y)[Math.floor(a.length / 2)];
const sum = (a) => a.reduce((x, y) => x + y, 0);
const on = costs.map((c) => med(c.on));
const off = costs.map((c) => med(c.off));
const q = (a, p) => [...a].sort((x, y) => x - y)[Math.min(a.length - 1, Math.ceil(p * a.length) - 1)];
console.log(`frames with hidden tiles or parts of tiles: ${costs.length} over ${views.length} views; tiles listed per frame mean ${(sum(costs.map((c) => c.tiles)) / costs.length).toFixed(1)}, hidden mean ${(sum(costs.map((c) => c.hidden)) / costs.length).toFixed(1)}`);
console.log(`Mpx rastered per such frame: without pruning ${(sum(costs.map((c) => c.pxOff)) / costs.length / 1e6).toFixed(2)}, with ${(sum(costs.map((c) => c.pxOn)) / costs.length / 1e6).toFixed(2)}`);
console.log(`full redraw + raster, ms per frame (median of 3 each): without pruning mean ${(sum(off) / off.length).toFixed(2)} p50 ${q(off, 0.5).toFixed(2)} p95 ${q(off, 0.95).toFixed(2)}; with pruning mean ${(sum(on) / on.length).toFixed(2)} p50 ${q(on, 0.5).toFixed(2)} p95 ${q(on, 0.95).toFixed(2)}`);
