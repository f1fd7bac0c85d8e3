// A IIIF viewer no one here wrote: Mirador (npm, its UMD build) opens a texture from nothing but
// the URL of its IIIF Presentation 3 Manifest, follows the Manifest to the Image API 3 service
// and draws the texture. Every screen pixel compared must be the server's own tile pixel at
// the level on screen, deep inside the texture and along its right and bottom edges.
// Run: node --test tests/browser/iiif.test.mjs   (needs target/release/vtex and client-web/dist)
import test, { after, before } from 'node:test';
import assert from 'node:assert/strict';
import { join } from 'node:path';
import { compareScreenToTexels, decodePng, launchBrowser, ROOT, startServer } from './lib.mjs';

const MIRADOR = join(ROOT, 'client-web', 'node_modules', 'mirador', 'dist', 'mirador.min.js');
const WINDOW = 'w';

let server;
let browser;
let info;

before(async () => {
  server = await startServer();
  browser = await launchBrowser();
  const { textures } = await (await fetch(`${server.url}/api/v1/textures`)).json();
  // A chaos mosaic (quick to synthesize) whose sides are not whole tiles, so its right and
  // bottom edge tiles are cut short; Mirador pans to its corner.
  info = textures
    .filter((t) => t.model === 'chaos-mosaic' && !t.animated && t.width % t.tile_size && t.height % t.tile_size)
    .sort((a, b) => a.width * a.height - b.width * b.height)[0];
  assert.ok(info, `a demo texture fits: ${textures.map((t) => `${t.width}×${t.height}`)}`);
});

after(async () => {
  await browser?.close();
  await server?.stop();
});

/** Mirador in an 800 × 600 page on the server's origin, its script served from node_modules. */
async function openMirador(manifestId) {
  const page = await browser.context.newPage();
  const log = { errors: [], bad: [], requests: [] };
  page.on('pageerror', (e) => log.errors.push(String(e)));
  // Mirador 4's bundled React 19 warns of Mirador's own use of `element.ref`: not this test's.
  const react = /^Accessing element\.ref was removed in React 19/;
  page.on('console', (m) => m.type() === 'error' && !react.test(m.text()) && log.errors.push(m.text()));
  page.on('request', (r) => log.requests.push(r.url()));
  page.on('response', (r) => r.status() >= 400 && log.bad.push(`${r.status()} ${r.url()}`));
  const html =
    '<!doctype html><html><body style="margin:0">' +
    '<div id="view" style="position:absolute;left:0;top:0;width:800px;height:600px"></div>' +
    '<script src="/mirador/mirador.min.js"></script></body></html>';
  await page.route(`${server.url}/mirador-test.html`, (route) => route.fulfill({ body: html, contentType: 'text/html' }));
  // The script is UTF-8: said so, or Chromium reads it as Latin-1 and fails to parse it.
  await page.route(`${server.url}/mirador/mirador.min.js`, (route) =>
    route.fulfill({ path: MIRADOR, contentType: 'text/javascript; charset=utf-8' }),
  );
  await page.goto(`${server.url}/mirador-test.html`);
  await page.evaluate(
    ([manifestId, windowId]) => {
      window.mirador = Mirador.viewer({
        id: 'view',
        windows: [{ id: windowId, manifestId, thumbnailNavigationPosition: 'off' }],
        window: { allowClose: false, allowMaximize: false, sideBarOpen: false, hideWindowTitle: true },
        workspaceControlPanel: { enabled: false },
        // No animation and no smoothing, so that a settled view shows texels as they are.
        // minPixelRatio under 1: at 1:2 OpenSeadragon draws level 1 pixel for pixel, not level 0
        // thinned, and at 1:1 level 0 (a ratio of exactly 1 may compute a hair under it).
        osdConfig: { animationTime: 0, blendTime: 0, imageSmoothingEnabled: false, maxZoomPixelRatio: 16, minPixelRatio: 0.9 },
      });
      window.osd = () => Mirador.OSDReferences.get(windowId)?.current;
      // Where level-0 image point (x, y) is on the page, and page pixels per level-0 texel.
      window.screenOf = (x, y) => {
        const viewer = window.osd();
        const item = viewer.world.getItemAt(0);
        const element = (x, y) => viewer.viewport.pixelFromPoint(item.imageToViewportCoordinates(x, y, true), true);
        const a = element(x, y);
        const b = element(x + 100, y + 100);
        const r = viewer.element.getBoundingClientRect();
        return { ax: a.x + r.left, ay: a.y + r.top, sx: (b.x - a.x) / 100, sy: (b.y - a.y) / 100 };
      };
    },
    [manifestId, WINDOW],
  );
  await settled(page);
  return { page, log };
}

/** Resolves when Mirador's OpenSeadragon has drawn every tile of the current view. */
async function settled(page) {
  await page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
  await page.waitForFunction(
    () => {
      const viewer = window.osd?.();
      const item = viewer?.world.getItemAt(0);
      return item && item.getFullyLoaded() && !viewer.world.needsDraw();
    },
    null,
    { timeout: 60_000, polling: 50 },
  );
}

/**
 * Shows level-0 image point (x, y) at the centre at `scale` screen pixels per texel, through
 * Mirador's own viewport action (its store then drives OpenSeadragon). Mirador pans, then zooms
 * about the new centre before the pan has landed, so the action is sent again once the zoom
 * has: then it only pans.
 */
async function showAt(page, x, y, scale) {
  const target = await page.evaluate(
    ([x, y, scale]) => {
      const item = window.osd().world.getItemAt(0);
      const c = item.imageToViewportCoordinates(x, y);
      return { x: c.x, y: c.y, zoom: item.imageToViewportZoom(scale) };
    },
    [x, y, scale],
  );
  for (const landed of ['zoom', 'centre']) {
    await page.evaluate(([t, id]) => window.mirador.store.dispatch(Mirador.updateViewport(id, t)), [target, WINDOW]);
    await page.waitForFunction(
      ([t, landed]) => {
        const vp = window.osd().viewport;
        const c = vp.getCenter(true);
        const zoomed = Math.abs(vp.getZoom(true) / t.zoom - 1) < 1e-9;
        return zoomed && (landed === 'zoom' || (Math.abs(c.x - t.x) < 1e-6 && Math.abs(c.y - t.y) < 1e-6));
      },
      [target, landed],
      { timeout: 10_000 },
    );
  }
  await settled(page);
}

/**
 * Compares the screen with the server's level-`level` tiles over the level-0 image rectangle
 * [x0, x1) × [y0, y1), shown at 2^-level screen pixels per texel. Returns the pixels compared.
 */
async function compareRect(page, level, x0, y0, x1, y1) {
  const at = await page.evaluate(([x, y]) => window.screenOf(x, y), [x0, y0]);
  const s = 2 ** -level;
  assert.ok(Math.abs(at.sx - s) < 1e-6 && Math.abs(at.sy - s) < 1e-6, `shown at ${at.sx} × ${at.sy}, not ${s}`);
  const clip = { x: Math.round(at.ax), y: Math.round(at.ay), width: Math.round((x1 - x0) * s), height: Math.round((y1 - y0) * s) };
  // compareScreenToTexels takes the level's own texels: scale the level-0 mapping to them.
  const k = 2 ** level;
  const atLevel = { ax: at.ax, ay: at.ay, sx: at.sx * k, sy: at.sy * k };
  const { compared } = await compareScreenToTexels(page, server.url, info, x0 / k, y0 / k, atLevel, clip, { level });
  return compared;
}

test("Mirador opens a texture's Presentation 3 manifest and draws the server's pixels, edges included", async () => {
  const manifestId = `${server.url}/iiif/presentation/3/${info.id}/manifest.json`;
  const { page, log } = await openMirador(manifestId);
  const { width: W, height: H, tile_size: ts } = info;
  // Mirador's OpenSeadragon picks its drawer: WebGL here as in a desktop browser, which draws
  // IIIF tiles edge to edge (the canvas drawer widens each by a pixel to hide seams).
  assert.equal(await page.evaluate(() => window.osd().drawer.getType()), 'webgl');

  // 1:1, deep inside: a 200² box around the corner of four level-0 tiles.
  const ix = ts * Math.floor(W / ts / 2);
  const iy = ts * Math.floor(H / ts / 2);
  await showAt(page, ix, iy, 1);
  assert.equal(await compareRect(page, 0, ix - 100, iy - 100, ix + 100, iy + 100), 200 * 200);

  // 1:1 and 1:2 with the bottom-right corner on screen: every pixel of the texture in view,
  // up to and including its last column and row (cut-short edge tiles, level 0 and level 1).
  for (const level of [0, 1]) {
    const s = 2 ** -level;
    // The texture's corner 200 px right of and 150 px below the centre of the 800 × 600 view.
    await showAt(page, W - 200 / s, H - 150 / s, s);
    const [x0, y0] = [Math.max(0, W - 500 / s), Math.max(0, H - 350 / s)];
    const compared = await compareRect(page, level, x0, y0, W, H);
    assert.ok(compared >= 0.99 * (W - x0) * (H - y0) * s * s, `level ${level}: compared ${compared} pixels`);
    // Beyond the edges Mirador shows its plain background, not texels stretched over it.
    const at = await page.evaluate(([x, y]) => window.screenOf(x, y), [W, H]);
    for (const clip of [
      { x: Math.round(at.ax) + 1, y: Math.round(at.ay) - 60, width: 40, height: 40 },
      { x: Math.round(at.ax) - 60, y: Math.round(at.ay) + 1, width: 40, height: 40 },
    ]) {
      const { data } = decodePng(await page.screenshot({ clip }));
      const first = data.readUInt32BE(0);
      for (let p = 0; p < data.length; p += 4) assert.equal(data.readUInt32BE(p), first, `level ${level}: beyond the edge at ${JSON.stringify(clip)}`);
    }
  }

  const tiles = log.requests.filter((u) => new URL(u).pathname.startsWith(`/iiif/3/${info.id}/`));
  assert.ok(tiles.length >= 4, `IIIF image requests: ${log.requests.slice(-5)}`);
  assert.ok(log.requests.includes(manifestId), 'Mirador read the manifest');
  assert.deepEqual(log.errors, []);
  assert.deepEqual(log.bad, []);
  await page.close();
});
