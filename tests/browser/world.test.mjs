// The 3D world (client-web/src/world.html) in headless Chromium's software WebGL against a real
// vtex serve: in client mode each texture's encoding and its model's module are fetched once and
// no page or tile ever; at fixed cameras its frame equals the frame drawn from the server's RGBA
// pages but for the GPU's rounding (below); BC7 KTX2 and JPEG pages draw the same world within their codecs' error.
// Run: node --test tests/browser/   (needs target/release/vtex and client-web/dist built)
import test, { after, before } from 'node:test';
import assert from 'node:assert/strict';
import { mkdirSync, writeFileSync } from 'node:fs';
import { join } from 'node:path';
import { debugUrl, decodePng, launchBrowser, ROOT, startServer, structure } from './lib.mjs';

const VIEW = { width: 640, height: 400 };
// x, y, eye height, yaw, pitch (scene.js: the courtyard is 3000 units a side about 50,000).
const CAMERAS = {
  // Facing the north wall and its board across the floor.
  board: '50000,51000,160,0,8',
  // Facing the north-west corner, looking down: floor levels 0 to 3, two walls, the board's end.
  corner: '50600,50800,160,-45,25',
};
const SHOTS = join(ROOT, 'target', 'browser');

let server;
let browser;

before(async () => {
  server = await startServer();
  browser = await launchBrowser(VIEW);
  mkdirSync(SHOTS, { recursive: true });
});

after(async () => {
  await browser?.close();
  await server?.stop();
});

/**
 * Opens the world with `query` until its fixed camera's view is complete: its canvas (decoded
 * screenshot, also written to target/browser/world-`name`.png), every URL asked for, and the
 * state.
 */
async function openWorld(name, query) {
  const page = await browser.context.newPage();
  const log = { errors: [], bad: [], urls: [] };
  page.on('pageerror', (e) => log.errors.push(String(e)));
  page.on('console', (m) => m.type() === 'error' && log.errors.push(m.text()));
  page.on('response', (r) => r.status() >= 400 && log.bad.push(`${r.status()} ${r.url()}`));
  page.on('request', (r) => log.urls.push(new URL(r.url()).pathname));
  await page.goto(debugUrl(`${server.url}/world.html?${query}`));
  await page.waitForFunction(() => window.vtexWorld && (window.vtexWorld.error || window.vtexWorld.state.settled), null, { timeout: 300_000, polling: 100 });
  const error = await page.evaluate(() => window.vtexWorld.error || window.vtexWorld.state.error);
  assert.equal(error, null, `${name}: the world reports no error`);
  const world = await page.evaluate(() => ({ textures: window.vtexWorld.state.textures, stats: window.vtexWorld.stats() }));
  await page.evaluate(() => {
    document.getElementById('overlay').hidden = true;
    document.getElementById('links').hidden = true;
  });
  const png = await page.locator('#view').screenshot();
  writeFileSync(join(SHOTS, `world-${name}.png`), png);
  await page.close();
  assert.deepEqual(log.errors, [], `${name}: no errors`);
  assert.deepEqual(log.bad, [], `${name}: no failed responses`);
  return { shot: decodePng(png), log, world };
}

/** Mean and largest |Δ| over the RGB channels of two screenshots of the same size. */
function difference(a, b) {
  assert.equal(a.data.length, b.data.length);
  let sum = 0;
  let worst = 0;
  let differing = 0;
  for (let i = 0; i < a.data.length; i += 4) {
    let any = false;
    for (let c = 0; c < 3; c++) {
      const d = Math.abs(a.data[i + c] - b.data[i + c]);
      sum += d;
      worst = Math.max(worst, d);
      any ||= d > 0;
    }
    if (any) differing++;
  }
  return { mean: sum / ((a.data.length / 4) * 3), worst, differing };
}

const pageRequests = (urls) => urls.filter((p) => /\/api\/v1\/textures\/\w+\/(pages|page-metatiles|tiles|metatiles|region)\b/.test(p));

const client = {};

test('client mode: each encoding and each model\'s module fetched once, then no page or tile; the world shows all three textures', async () => {
  for (const [name, camera] of Object.entries(CAMERAS)) {
    const { shot, log, world } = await openWorld(`client-${name}`, `camera=${camera}`);
    client[name] = shot;
    assert.deepEqual(world.textures.map((t) => t.model), ['chaos-mosaic', 'cascade', 'patterns']);
    const encodings = log.urls.filter((p) => p.endsWith('/encoding')).sort();
    assert.deepEqual(encodings, world.textures.map((t) => `/api/v1/textures/${t.id}/encoding`).sort(), 'each encoding once');
    const modules = [...new Set(world.textures.map((t) => `/vtex_synth_${t.model}.wasm`))].sort();
    assert.deepEqual(log.urls.filter((p) => p.endsWith('.wasm')).sort(), modules, "each model's module once");
    assert.deepEqual(pageRequests(log.urls), [], 'no page, tile or region asked of the server');
    assert.equal(world.stats.requests.pages, 0);
    // The first page fetches them; the next finds them in the browser's cache.
    if (name === 'board') assert.ok(world.stats.bytes.encodings > 0 && world.stats.bytes.module > 0, JSON.stringify(world.stats.bytes));
    const { colours, sd } = structure(shot);
    assert.ok(colours >= 30 && sd >= 20, `${name}: a textured view, not a flat one (${colours} colours, σ ${sd.toFixed(1)})`);
  }
});

test('at fixed cameras client mode draws the same pixels as the server’s RGBA pages', async () => {
  for (const [name, camera] of Object.entries(CAMERAS)) {
    const { shot, log, world } = await openWorld(`rgba-${name}`, `pages=rgba&camera=${camera}`);
    const pages = pageRequests(log.urls);
    assert.ok(pages.length > 0 && pages.every((p) => p.endsWith('.rgba')), `${name}: pages fetched as RGBA (${pages.length})`);
    assert.ok(world.stats.bytes.pages > 0);
    assert.deepEqual(log.urls.filter((p) => p.endsWith('/encoding') || p.endsWith('.wasm')), [], 'no encoding, no module');
    // The same page bytes (the module renders the server's region exactly), the same GPU, the
    // same camera: the same frame but for the atlas slots the pages landed in, which follow the
    // order they arrived in. A texel's atlas coordinate, (slot · 136 + 4 + offset) / side in
    // float32, rounds differently in another slot by about 10⁻⁴ texel, which can tip the GPU's
    // 8-bit bilinear weights by one step: a channel off by 1 in a few pixels (measured: about
    // 130 of 256,000, by 1). A page misplaced by a texel or of the wrong level changes most
    // pixels, by tens.
    const d = difference(shot, client[name]);
    console.log(`# ${name}: client against server RGBA pages: ${d.differing} of ${VIEW.width * VIEW.height} pixels differ, max |Δ| ${d.worst}`);
    assert.ok(d.worst <= 1, `${name}: max |Δ| ${d.worst}`);
    assert.ok(d.differing <= (VIEW.width * VIEW.height) / 200, `${name}: ${d.differing} pixels differ`);
  }
});

test('BC7 KTX2 and JPEG pages draw the same world within their codecs’ error', async () => {
  for (const [mode, ext, tolerance] of [
    ['ktx2', '.ktx2', 3],
    ['jpg', '.jpg', 4],
  ]) {
    const { shot, log } = await openWorld(`${mode}-board`, `pages=${mode}&camera=${CAMERAS.board}`);
    const pages = pageRequests(log.urls);
    assert.ok(pages.length > 0 && pages.every((p) => p.endsWith(ext)), `${mode}: pages fetched as ${ext}`);
    const d = difference(shot, client.board);
    console.log(`# ${mode} against client pages: mean |Δ| ${d.mean.toFixed(2)}, max ${d.worst}`);
    // Lossy codecs: BC7 and JPEG at the server's quality move a texel by a few levels on
    // average; a page misplaced or a level wrong moves it by tens.
    assert.ok(d.mean <= tolerance, `${mode}: mean |Δ| ${d.mean.toFixed(2)} over ${tolerance}`);
  }
});
