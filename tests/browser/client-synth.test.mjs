// The viewer's client mode (?synth=client): tiles synthesized in the page by the WebAssembly
// module from the encoding, byte for byte the server's, for every model and for animation
// frames; exploring on with the server stopped; bad encodings shown as messages in the page.
// Run: node --test tests/browser/   (needs target/release/vtex and client-web/dist built with
// the wasm modules; see scripts/test)
import test, { after, before } from 'node:test';
import assert from 'node:assert/strict';
import {
  closeSession,
  compareScreenToServerTile,
  debugUrl,
  openViewer,
  setAlignedView,
  startServer,
  startSession,
  waitForIdle,
} from './lib.mjs';

let server;
let browser;
let textures;

// A small window: fewer tiles to synthesize per view, the same checks.
before(async () => ({ server, browser, textures } = await startSession({ browserSize: { width: 800, height: 520 } })));
after(() => closeSession({ server, browser }));

const tileRequests = (urls) => urls.filter((u) => /\/api\/v1\/textures\/[^/]+\/(meta)?tiles/.test(u));
const encodingRequests = (urls) => urls.filter((u) => /\/api\/v1\/textures\/[^/]+\/encoding$/.test(u));
const moduleRequests = (urls) => urls.filter((u) => /\/vtex_synth[^/]*\.wasm$/.test(u));

/** The largest texture of each model, and the largest animated one. */
function flagships() {
  const byArea = [...textures].sort((a, b) => b.width * b.height - a.width * a.height);
  const picks = [...new Set(textures.map((t) => t.model))].sort().map((m) => byArea.find((t) => t.model === m));
  return [...picks, byArea.find((t) => t.animated)];
}

/**
 * In the page: tiles synthesized by the client (raw RGBA from its Workers) against the
 * server's `.rgba` tiles, fetched by the page. Answers the tiles that differ.
 */
function compareTilesInPage(tiles) {
  const { state } = window.vtexViewer;
  return Promise.all(
    tiles.map(async ({ level, x, y, frame }) => {
      const info = state.info;
      const mine = await state.synth.tile(level, x, y, frame, { raw: true }).promise;
      const q = info.animated ? `?frame=${frame}` : '';
      const theirs = new Uint8Array(await (await fetch(`/api/v1/textures/${info.id}/tiles/${level}/${x}/${y}.rgba${q}`)).arrayBuffer());
      const same = mine.bytes.length === theirs.length && mine.bytes.every((b, i) => b === theirs[i]);
      return same ? null : `${level}/${x}/${y}@${frame}: ${mine.bytes.length} bytes against ${theirs.length}`;
    }),
  ).then((r) => r.filter(Boolean));
}

test('client mode draws every model (and an animation frame) exactly as the server, with no tile request', async (t) => {
  for (const info of flagships()) {
    const frame = info.animated ? 37 : 0;
    await t.test(`${info.model} “${info.name}”${info.animated ? ' at frame 37' : ''}`, async () => {
      // Opened zoomed out (the zoom is held at the whole texture): the views checked are set below.
      const { page, log } = await openViewer(browser.context, `${server.url}/?texture=${info.id}&synth=client&frame=${frame}&zoom=0.001`);
      await waitForIdle(page, 120_000);
      const described = await page.evaluate(() => window.vtexViewer.state.synth.ready);
      assert.deepEqual(described, info, "the module's info is the server's");
      // Level 0 and level 2 at 1:1, away from the origin, each patch inside one tile.
      const at = (size, offset) => 1024 * Math.max(0, Math.floor((Math.min(9_000, size - 300) - offset) / 1024)) + offset;
      const x0 = at(info.width, 40);
      const y0 = at(info.height, 20);
      await setAlignedView(page, 1, x0, y0);
      assert.deepEqual(await page.evaluate(() => window.vtexViewer.drawnLevels()), [0]);
      assert.equal(await compareScreenToServerTile(page, server.url, info, 0, x0, y0, 32, frame), 0, 'level-0 pixels exact');
      await setAlignedView(page, 1 / 4, x0, y0);
      assert.deepEqual(await page.evaluate(() => window.vtexViewer.drawnLevels()), [2]);
      assert.equal(await compareScreenToServerTile(page, server.url, info, 2, x0 >> 2, y0 >> 2, 32, frame), 0, 'level-2 pixels exact');
      assert.deepEqual(tileRequests(log.requests), [], 'no tile requested from the server by the viewer');
      assert.equal(encodingRequests(log.requests).length, 1, 'the encoding fetched once');
      assert.deepEqual(moduleRequests(log.requests), [`${server.url}/vtex_synth_${info.model}.wasm`], "only the module of the texture's model");
      // Tile bytes in the page: level 0, the last (clipped) tile of level 0, a middle level, the coarsest.
      const n = (level) => [Math.ceil(Math.ceil(info.width / 2 ** level) / info.tile_size), Math.ceil(Math.ceil(info.height / 2 ** level) / info.tile_size)];
      const mid = info.levels >> 1;
      const tiles = [
        { level: 0, x: 3, y: 2, frame },
        { level: 0, x: n(0)[0] - 1, y: n(0)[1] - 1, frame },
        { level: mid, x: n(mid)[0] >> 1, y: n(mid)[1] >> 1, frame },
        { level: info.levels - 1, x: 0, y: 0, frame },
      ];
      assert.deepEqual(await page.evaluate(compareTilesInPage, tiles), []);
      const s = await page.evaluate(() => window.vtexViewer.stats.snapshot());
      assert.equal(s.failed, 0, `failed tiles: ${s.lastError}`);
      assert.deepEqual(log.errors, [], 'console errors');
      await page.close();
    });
  }
});

test('client mode keeps panning and zooming with the server stopped', async () => {
  const own = await startServer();
  try {
    const list = (await (await fetch(`${own.url}/api/v1/textures`)).json()).textures;
    const mosaic = list.find((t) => t.model === 'chaos-mosaic' && t.width >= 100_000);
    const { page, log } = await openViewer(browser.context, `${own.url}/?texture=${mosaic.id}&synth=client`);
    await waitForIdle(page, 120_000);
    await own.stop();
    const before = await page.evaluate(() => window.vtexViewer.stats.snapshot());
    const requestsBefore = log.requests.length;
    for (const [zoom, x, y] of [[1 / 16, 50_000, 50_000], [1, 73_000, 41_000], [2, 12_345, 98_765]]) {
      await setAlignedView(page, zoom, x, y);
    }
    assert.deepEqual(await page.evaluate(() => window.vtexViewer.drawnLevels()), [0]);
    const after = await page.evaluate(() => window.vtexViewer.stats.snapshot());
    assert.ok(after.loaded > before.loaded + 10, `${after.loaded - before.loaded} tiles made with the server stopped`);
    assert.equal(after.failed, 0, `failed tiles: ${after.lastError}`);
    assert.deepEqual(log.requests.slice(requestsBefore), [], 'no request once the encoding is in');
    assert.equal(await page.locator('#error').isHidden(), true);
    await page.close();
  } finally {
    await own.stop();
  }
});

/** Opens `info` in client mode with its encoding answered by `body` (bytes of the real one). */
async function openWithEncoding(info, edit) {
  const page = await browser.context.newPage();
  const errors = [];
  page.on('pageerror', (e) => errors.push(String(e)));
  await page.route('**/api/v1/textures/*/encoding', async (route) => {
    const real = new Uint8Array(await (await route.fetch()).body());
    await route.fulfill({ status: 200, contentType: 'application/octet-stream', body: Buffer.from(edit(real)) });
  });
  await page.goto(debugUrl(`${server.url}/?texture=${info.id}&synth=client`));
  await page.waitForFunction(() => !document.getElementById('error').hidden, null, { timeout: 60_000 });
  return { page, errors, message: await page.locator('#error').textContent() };
}

test('a truncated, corrupted, foreign, other-model or unknown-version encoding is a clear message, and the page works on', async () => {
  const info = textures.find((t) => t.model === 'chaos-mosaic' && t.width >= 100_000);
  const bytesOf = async (t) => new Uint8Array(await (await fetch(`${server.url}/api/v1/textures/${t.id}/encoding`)).arrayBuffer());
  const otherBytes = await bytesOf(textures.find((t) => t.model === 'chaos-mosaic' && t.id !== info.id));
  const otherModelBytes = await bytesOf(textures.find((t) => t.model === 'lcm'));
  const cases = [
    ['truncated', (b) => b.slice(0, b.length >> 1), /is not possible: invalid bundle: truncated: section `.+` needs \d+ bytes, \d+ left/],
    ['an unknown version', (b) => { const c = b.slice(); new DataView(c.buffer).setUint32(8, 2, true); return c; }, /invalid bundle: container version 2; this build reads 1/],
    ['corrupted', (b) => { const c = b.slice(); c[20] ^= 0xff; return c; }, /is not possible: invalid bundle: manifest/],
    ['another texture’s', () => otherBytes, /the encoding received is not this texture's: its content id is [0-9a-f]{64}, expected [0-9a-f]{64}/],
    ['another model’s', () => otherModelBytes, /is not possible: model `lcm` is not in this build, which holds only: chaos-mosaic$/],
  ];
  for (const [what, edit, pattern] of cases) {
    const { page, errors, message } = await openWithEncoding(info, edit);
    assert.match(message, new RegExp(`^Client synthesis of “${info.name.replace(/[()]/g, '.')}” is not possible: `), what);
    assert.match(message, pattern, what);
    assert.deepEqual(errors, [], `${what}: uncaught errors in the page`);
    // The page still works: back to server tiles, the view fills.
    await page.selectOption('#synth', 'server');
    await waitForIdle(page, 60_000);
    assert.equal(await page.locator('#error').isHidden(), true, `${what}: the message goes once the server makes the tiles`);
    await page.close();
  }
});
