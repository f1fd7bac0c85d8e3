// End-to-end tests of the viewer: headless Chromium against a real `vtex serve`.
// Run: node --test tests/browser/   (needs target/release/vtex and client-web/dist built)
import test, { after, before } from 'node:test';
import assert from 'node:assert/strict';
import {
  closeSession,
  compareScreenToServerTile,
  compareScreenToTexels,
  decodePng,
  openViewer,
  screenPointOf,
  setAlignedView,
  startSession,
  tileRequests,
  waitForIdle,
} from './lib.mjs';
import { inPyramid } from '../../client-web/src/viewer/pyramid.js';

let server;
let browser;
let textures;
let big;

before(async () => {
  ({ server, browser, textures } = await startSession());
  big = textures.find((t) => t.width >= 100_000 && t.height >= 100_000);
  assert.ok(big, `the demo textures include a 100k × 100k one: ${textures.map((t) => `${t.name} ${t.width}×${t.height}`)}`);
});

after(() => closeSession({ server, browser }));

/** The viewer's metatile requests among `urls`. */
const metatileRequests = (urls) => urls.filter((u) => /\/api\/v1\/textures\/[^/]+\/metatiles\//.test(u));

/** No console errors, no failed or 4xx/5xx requests, every tile request inside its pyramid. */
function assertClean(log) {
  assert.deepEqual(log.errors, [], 'console errors');
  // The viewer aborts a metatile once none of its tiles is wanted (a view left): not a failure.
  const aborted = (f) => f.endsWith('net::ERR_ABORTED') && metatileRequests([f.split(': ')[0]]).length === 1;
  assert.deepEqual(log.failed.filter((f) => !aborted(f)), [], 'failed requests');
  assert.deepEqual(log.badResponses, [], 'error responses');
  for (const t of tileRequests(log.requests)) {
    const info = textures.find((i) => i.id === t.id);
    assert.ok(info, `tile of a listed texture: ${t.id}`);
    const side = t.metatile ? info.metatile : 1;
    assert.ok(inPyramid(info, t.level, t.x * side, t.y * side), `${t.metatile ? 'metatile' : 'tile'} ${t.level}/${t.x}/${t.y} lies inside the pyramid of ${info.name}`);
  }
  for (const u of log.requests) {
    const path = new URL(u).pathname;
    assert.ok(!/^https?:/.test(u) || u.startsWith(server.url), `request to another origin: ${u}`);
    assert.ok(path.startsWith('/api/v1/') || !path.startsWith('/api'), `unexpected API request ${path}`);
  }
}

const compareScreenToTile = (page, info, level, lx, ly, size, frame) =>
  compareScreenToServerTile(page, server.url, info, level, lx, ly, size, frame);

/**
 * Sets a magnified view (zoom > 1, at a fractional offset) and checks that every screen pixel
 * of a `size`² box at the centre shows exactly the level-0 texel under its centre: no seams,
 * no stretched tiles, no smoothing. Returns the number of pixels compared.
 */
async function checkMagnified(page, info, zoom, x, y, size = 240) {
  await page.evaluate(
    ([zoom, x, y]) => {
      window.vtexViewer.setView({ zoom, x, y }, true);
      window.vtexViewer.viewer.viewport.applyConstraints(true);
    },
    [zoom, x, y],
  );
  await waitForIdle(page);
  const a = await screenPointOf(page, x, y);
  const b = await screenPointOf(page, x + 100, y + 100);
  const sx = (b.px - a.px) / 100;
  const sy = (b.py - a.py) / 100;
  const clip = { x: Math.round(a.px - size / 2), y: Math.round(a.py - size / 2), width: size, height: size };
  const { compared, tiles } = await compareScreenToTexels(page, server.url, info, x, y, { ax: a.px, ay: a.py, sx, sy }, clip);
  assert.ok(tiles >= 2, 'the box spans a tile boundary');
  return compared;
}

test('the page loads cleanly, requests tiles and draws them', async () => {
  const { page, log } = await openViewer(browser.context, `${server.url}/`);
  await waitForIdle(page);
  const blocks = tileRequests(log.requests);
  assert.ok(blocks.length > 0, 'tiles were requested');
  const drawn = await page.evaluate(() => window.vtexViewer.drawnLevels());
  assert.ok(drawn.length > 0, 'tiles were drawn');
  // The info panel shows encoding bytes beside the explicit texture's bytes.
  const info = await page.locator('#info').innerText();
  assert.match(info, /Encoding/);
  assert.match(info, /Explicit/);
  assert.match(info, / : 1/);
  const stats = await page.evaluate(() => window.vtexViewer.stats.snapshot());
  assert.ok(blocks.every((t) => t.metatile), 'every tile was asked for in a metatile');
  assert.equal(stats.batches, metatileRequests(log.requests).length, 'the stats count every request');
  assert.ok(stats.batches < stats.requested, `fewer requests (${stats.batches}) than tiles (${stats.requested})`);
  const side = (await page.evaluate(() => window.vtexViewer.state.info)).metatile;
  assert.ok(stats.requested <= side * side * stats.batches, 'no tile outside the metatiles asked for');
  assert.equal(stats.failed, 0);
  assert.equal(stats.loaded + stats.aborted, stats.requested, 'every tile asked for was loaded or aborted');
  assert.equal(stats.serverHits + stats.serverMisses, stats.loaded, 'the cache state read on every tile');
  // Bytes on the wire, forwarded from the Worker's Resource Timing: the bodies of the tiles
  // drawn, those of the metatiles' other tiles, and the frame and HTTP headers.
  const overhead = stats.wireBytes - stats.bodyBytes;
  const most = side * side * (stats.bodyBytes + 64 * stats.requested) + 1024 * stats.batches;
  assert.ok(stats.aborted > 0 || (overhead > 0 && stats.wireBytes < most), `wire ${stats.wireBytes} B against bodies ${stats.bodyBytes} B`);
  // The view's canvas is opaque (osd-adapter.js vtexDrawer).
  const alpha = await page.evaluate(() => window.vtexViewer.viewer.drawer.context.getContextAttributes().alpha);
  assert.equal(alpha, false, "the view's canvas has no alpha channel");
  assertClean(log);
  await page.close();
});

test('the page names every module its script imports up front, so none waits for its importer', async () => {
  const { page, log } = await openViewer(browser.context, `${server.url}/`);
  await waitForIdle(page);
  const { preloaded, entry, fetched } = await page.evaluate(() => ({
    preloaded: [...document.querySelectorAll('link[rel=modulepreload]')].map((l) => l.href),
    entry: document.querySelector('script[type=module]').src,
    fetched: performance.getEntriesByType('resource').map((e) => e.name).filter((n) => n.endsWith('.js')),
  }));
  // Not OpenSeadragon (a classic script) nor the Workers' scripts, which the page does not import.
  const modules = fetched.filter((n) => n !== entry && !n.includes('/osd/') && !n.includes('/workers/'));
  assert.ok(modules.length >= 10, `the viewer's modules were fetched: ${modules}`);
  assert.deepEqual(modules.filter((n) => !preloaded.includes(n)), [], 'modules fetched without a modulepreload');
  assertClean(log);
  await page.close();
});

test('every private OpenSeadragon member the adapter relies on exists on the loaded library', async () => {
  const { page, log } = await openViewer(browser.context, `${server.url}/?texture=${big.id}&zoom=0.02&x=50000&y=50000`);
  await waitForIdle(page);
  const found = await page.evaluate(async () => {
    const { OSD_VERSION, PRIVATE_MEMBERS, checkVersion } = await import('/viewer/osd-adapter.js');
    const { viewer, state } = window.vtexViewer;
    const members = PRIVATE_MEMBERS.map(({ path, type }) => {
      const [root, ...rest] = path.split('.');
      let value = root === 'viewer' ? viewer : OpenSeadragon[root];
      for (const key of rest) value = value == null ? undefined : value[key];
      return { path, expected: type, actual: typeof value };
    });
    let refused = null;
    try {
      checkVersion({ version: { versionStr: '6.2.0' } });
    } catch (e) {
      refused = e.message;
    }
    // What the drawer draws for a tile on screen: its private cache, the tile's bitmap as `canvas`.
    const tile = state.item.getTilesToDraw()[0].tile;
    const data = viewer.drawer.getDataToDraw(tile);
    return {
      loaded: OpenSeadragon.version.versionStr,
      OSD_VERSION,
      members,
      refused,
      drawn: Object.prototype.toString.call(data && data.canvas),
      navigatorDrawer: viewer.navigator.drawer instanceof viewer.drawer.constructor,
    };
  });
  assert.equal(found.loaded, found.OSD_VERSION, 'the OpenSeadragon the page loads is the one osd-adapter.js was written for');
  for (const m of found.members) assert.equal(m.actual, m.expected, `OpenSeadragon ${found.loaded}: ${m.path} is a ${m.expected}`);
  assert.match(found.refused ?? '', /written for OpenSeadragon 6\.1\.1, but 6\.2\.0 is loaded/, 'another version is refused');
  assert.equal(found.drawn, '[object ImageBitmap]', 'tiles are drawn from their ImageBitmaps');
  assert.ok(found.navigatorDrawer, 'the navigator draws with the same drawer');
  // The refusal is logged loudly too: the only console error.
  assert.deepEqual(log.errors, [found.refused]);
  log.errors.length = 0;
  assertClean(log);
  await page.close();
});

for (const format of ['rgba', 'png', 'webp']) {
  test(`drawn pixels equal the server tiles (${format}): level 0 and level 3 at 1:1, level 0 magnified`, async () => {
    const { page, log } = await openViewer(browser.context, `${server.url}/?texture=${big.id}&format=${format}`);
    await waitForIdle(page);
    // Level 0 at 1:1, deep inside the texture.
    await setAlignedView(page, 1, 73_000, 41_000);
    assert.deepEqual(await page.evaluate(() => window.vtexViewer.drawnLevels()), [0]);
    assert.equal(await compareScreenToTile(page, big, 0, 73_000, 41_000), 0, 'level-0 pixels exact');
    // Level 3 drawn at 1:1 (zoom 1/8).
    await setAlignedView(page, 1 / 8, 8 * 9_000, 8 * 5_000);
    assert.deepEqual(await page.evaluate(() => window.vtexViewer.drawnLevels()), [3]);
    assert.equal(await compareScreenToTile(page, big, 3, 9_000, 5_000), 0, 'level-3 pixels exact');
    // Magnified 3.3× across the corner of four level-0 tiles.
    assert.ok((await checkMagnified(page, big, 3.3, 285 * 256 + 0.37, 160 * 256 + 0.81)) > 40_000);
    assert.ok(tileRequests(log.requests).every((t) => t.format === format), `every tile fetched as ${format}`);
    assertClean(log);
    await page.close();
  });
}

test('drag, wheel, keys, double-click and pinch move the view; the navigator box follows', async () => {
  const { page, log } = await openViewer(browser.context, `${server.url}/?texture=${big.id}&zoom=0.02&x=50000&y=50000`);
  await waitForIdle(page);
  const box = () => page.locator('.displayregion').boundingBox();
  const canvas = await page.locator('#osd').boundingBox();
  const cx = canvas.x + canvas.width / 2;
  const cy = canvas.y + canvas.height / 2;

  const before = await box();
  let count = tileRequests(log.requests).length;
  await page.mouse.move(cx, cy);
  await page.mouse.down();
  for (let i = 1; i <= 10; i++) await page.mouse.move(cx - 30 * i, cy - 20 * i);
  await page.mouse.up();
  await waitForIdle(page);
  const afterDrag = await box();
  assert.ok(tileRequests(log.requests).length > count, 'the drag requested new tiles');
  assert.ok(afterDrag.x > before.x + 2 && afterDrag.y > before.y + 1, `navigator box moved right and down: ${JSON.stringify([before, afterDrag])}`);
  const viewAfterDrag = await page.evaluate(() => window.vtexViewer.getView());
  assert.ok(viewAfterDrag.x > 50_000 + 10_000 && viewAfterDrag.y > 50_000 + 5_000, 'the view moved with the drag');

  count = tileRequests(log.requests).length;
  await page.mouse.move(cx, cy);
  for (let i = 0; i < 5; i++) {
    await page.mouse.wheel(0, -120);
    await page.waitForTimeout(60);
  }
  await waitForIdle(page);
  const afterWheel = await box();
  const zoomed = await page.evaluate(() => window.vtexViewer.getView());
  assert.ok(zoomed.zoom > viewAfterDrag.zoom * 1.5, 'wheel zoomed in');
  assert.ok(afterWheel.width < afterDrag.width * 0.75, 'navigator box shrank');
  assert.ok(tileRequests(log.requests).length > count, 'the wheel zoom requested new tiles');

  // Keyboard and double-click go through OpenSeadragon's own handlers.
  await page.locator('#osd .openseadragon-canvas').first().focus();
  const beforeKey = await page.evaluate(() => window.vtexViewer.getView());
  // One key at a time: while a zoom key is held OpenSeadragon ignores the arrow keys.
  await page.keyboard.press('ArrowRight');
  await waitForIdle(page);
  await page.keyboard.press('-');
  await waitForIdle(page);
  const afterKey = await page.evaluate(() => window.vtexViewer.getView());
  assert.ok(afterKey.x !== beforeKey.x, 'arrow key panned');
  assert.ok(afterKey.zoom < beforeKey.zoom, 'minus key zoomed out');
  await page.mouse.dblclick(cx, cy);
  await waitForIdle(page);
  const afterDbl = await page.evaluate(() => window.vtexViewer.getView());
  assert.ok(afterDbl.zoom > afterKey.zoom * 1.5, 'double-click zoomed in');
  // A two-finger pinch (touch events synthesised by Chromium).
  const cdp = await browser.context.newCDPSession(page);
  await cdp.send('Input.synthesizePinchGesture', { x: cx, y: cy, scaleFactor: 0.4, gestureSourceType: 'touch' });
  await waitForIdle(page);
  const afterPinch = await page.evaluate(() => window.vtexViewer.getView());
  assert.ok(afterPinch.zoom < afterDbl.zoom / 1.5, `pinch zoomed out (${afterDbl.zoom} → ${afterPinch.zoom})`);
  await cdp.detach();
  assertClean(log);
  await page.close();
});

test('many fast wheel zooms reach level 0 around (73000, 41000) cleanly', async () => {
  const { page, log } = await openViewer(browser.context, `${server.url}/?texture=${big.id}&zoom=0.005&x=73000&y=41000`);
  await waitForIdle(page);
  const at = await screenPointOf(page, 73_000, 41_000);
  await page.mouse.move(at.px, at.py);
  // Faster than the zoom animation (0.5 s); OpenSeadragon drops wheel events < 50 ms apart.
  for (let i = 0; i < 36; i++) {
    await page.mouse.wheel(0, -100);
    await page.waitForTimeout(55);
  }
  await waitForIdle(page);
  const view = await page.evaluate(() => window.vtexViewer.getView());
  assert.ok(view.zoom >= 1, `zoomed to full resolution (zoom ${view.zoom})`);
  assert.ok(Math.abs(view.x - 73_000) < 2000 && Math.abs(view.y - 41_000) < 2000, 'zoomed around the cursor');
  assert.deepEqual(await page.evaluate(() => window.vtexViewer.drawnLevels()), [0], 'level-0 tiles on screen');
  const level0 = tileRequests(log.requests).filter((t) => t.level === 0);
  const under = (v) => Math.floor(v / 256 / big.metatile);
  assert.ok(level0.some((t) => t.x === under(73_000) && t.y === under(41_000)), 'the level-0 metatile under (73000, 41000) was requested');
  // The readout names the level-0 pixel under the cursor.
  const here = await screenPointOf(page, 73_000.5, 41_000.5);
  await page.mouse.move(here.px, here.py);
  assert.equal(await page.locator('#coords').innerText(), 'x 73,000, y 41,000');
  // Nothing is left behind: the batches of views zoomed through run to their end (OpenSeadragon
  // has no way to give up a batched tile but failing it), then every tile asked for was loaded
  // or aborted and no job is still started.
  await page.waitForFunction(() => window.vtexViewer.state.item.source.vtexInFlight.size === 0, null, { timeout: 60_000 });
  const stats = await page.evaluate(() => window.vtexViewer.stats.snapshot());
  assert.equal(stats.failed, 0);
  assert.equal(stats.loaded + stats.aborted, stats.requested, JSON.stringify(stats));
  assert.ok(stats.batches < stats.requested, `in metatiles: ${stats.batches} requests for ${stats.requested} tiles`);
  assertClean(log);
  if (process.env.VTEX_SHOT_DIR) await page.screenshot({ path: `${process.env.VTEX_SHOT_DIR}/level0.png` });
  await page.close();
});

test('switching textures with the picker shows the other texture', async () => {
  assert.ok(textures.length >= 2, 'the server lists at least two textures');
  const { page, log } = await openViewer(browser.context, `${server.url}/?texture=${big.id}`);
  await waitForIdle(page);
  const other = textures.find((t) => t.id !== big.id);
  await page.selectOption('#texture-picker', other.id);
  await page.waitForFunction((id) => window.vtexViewer.state.info.id === id && window.vtexViewer.state.item?.source.vtexInfo.id === id, other.id);
  await waitForIdle(page);
  assert.ok(tileRequests(log.requests).some((t) => t.id === other.id), 'tiles of the new texture requested');
  assert.match(await page.locator('#info').innerText(), new RegExp(other.name.replace(/[.*+?^${}()|[\]\\]/g, '\\$&')));
  await page.waitForFunction((id) => new URLSearchParams(location.search).get('texture') === id, other.id);
  const view = await page.evaluate(() => window.vtexViewer.getView());
  assert.ok(Math.abs(view.x - other.width / 2) < other.width * 0.01, 'the new texture opens centred');
  // Rapid switching: the last pick wins.
  for (const id of [big.id, other.id, big.id, other.id, big.id]) await page.selectOption('#texture-picker', id);
  await page.waitForFunction((id) => window.vtexViewer.state.item?.source.vtexInfo.id === id, big.id);
  await waitForIdle(page);
  assert.equal(await page.evaluate(() => window.vtexViewer.viewer.world.getItemCount()), 1);
  assert.equal(await page.evaluate(() => window.vtexViewer.getView().texture), big.id);
  assertClean(log);
  await page.close();
});

test('the detail setting picks the level drawn, and a link keeps it', async () => {
  // At zoom 0.6 `map` (the default) draws level 1 magnified 1.2 ×, `sharp` level 0 at 0.6.
  const { page, log } = await openViewer(browser.context, `${server.url}/?texture=${big.id}&zoom=0.6&x=40000&y=40000`);
  const finest = async () => {
    await waitForIdle(page);
    return (await page.evaluate(() => window.vtexViewer.drawnLevels()))[0];
  };
  assert.equal(await finest(), 1, 'map');
  assert.equal(Math.min(...tileRequests(log.requests).map((t) => t.level)), 1, 'map: the finest level fetched');
  await page.locator('#detail').selectOption('sharp');
  assert.equal(await finest(), 0, 'sharp');
  await page.waitForTimeout(400); // the URL is written 150 ms after the view settles
  const link = page.url();
  assert.match(link, /detail=sharp/);
  const again = await openViewer(browser.context, link);
  await waitForIdle(again.page);
  assert.deepEqual(await again.page.evaluate(() => window.vtexViewer.drawnLevels()), [0], 'sharp, from the link');
  assert.equal(await again.page.locator('#detail').inputValue(), 'sharp');
  assertClean(log);
  assertClean(again.log);
  await page.close();
  await again.page.close();
});

test("a tile the server refuses fails with the server's message, and the viewer serves on", async () => {
  const { page, log } = await openViewer(browser.context, `${server.url}/?texture=${big.id}&zoom=0.02&x=50000&y=50000`);
  await waitForIdle(page);
  // A job for a tile outside level 0, handed straight to the tile source (OpenSeadragon never
  // asks for one: tileExists), goes out as a metatile the server refuses.
  const failure = await page.evaluate(
    () =>
      new Promise((resolve) => {
        const source = window.vtexViewer.state.item.source;
        const tile = { level: source.maxLevel, x: 1_000_000, y: 0 };
        source.downloadTileStart({
          src: 'out of range',
          tile,
          userData: {},
          finish: (data) => resolve({ data: Boolean(data), error: null }),
          fail: (error) => resolve({ data: false, error }),
        });
      }),
  );
  assert.equal(failure.data, false);
  assert.match(failure.error, /HTTP 404 .*metatile 0\/500000\/0 is outside level 0/);
  const stats = await page.evaluate(() => window.vtexViewer.stats.snapshot());
  assert.equal(stats.failed, 1);
  assert.match(stats.lastError, /outside level 0/);
  // The viewer goes on: a new view loads and draws.
  await page.evaluate(() => window.vtexViewer.setView({ zoom: 0.5, x: 12_000, y: 80_000 }, true));
  await waitForIdle(page);
  assert.deepEqual(await page.evaluate(() => window.vtexViewer.drawnLevels()), [1]);
  assert.deepEqual(log.errors, [], 'console errors');
  assert.equal(log.badResponses.length, 1, `the refused metatile only: ${log.badResponses}`);
  await page.close();
});

test('a permalink restores the view', async () => {
  const { page, log } = await openViewer(browser.context, `${server.url}/?texture=${big.id}&zoom=0.3&x=31000&y=62000`);
  await waitForIdle(page);
  // Move somewhere by dragging, then take the link the page now shows.
  const canvas = await page.locator('#osd').boundingBox();
  await page.mouse.move(canvas.x + 400, canvas.y + 300);
  await page.mouse.down();
  await page.mouse.move(canvas.x + 250, canvas.y + 200, { steps: 8 });
  await page.mouse.up();
  await page.mouse.move(canvas.x + 300, canvas.y + 300);
  await page.mouse.wheel(0, -240);
  await waitForIdle(page);
  await page.waitForTimeout(400); // the URL is written 150 ms after the view settles
  const view = await page.evaluate(() => window.vtexViewer.getView());
  const link = page.url();
  assert.match(link, /texture=/);
  const shot = decodePng(await page.locator('#osd').screenshot());

  const again = await openViewer(browser.context, link);
  await waitForIdle(again.page);
  const restored = await again.page.evaluate(() => window.vtexViewer.getView());
  assert.equal(restored.texture, view.texture);
  assert.ok(Math.abs(restored.zoom / view.zoom - 1) < 1e-4, `zoom ${restored.zoom} vs ${view.zoom}`);
  assert.ok(Math.abs(restored.x - view.x) < 0.5 && Math.abs(restored.y - view.y) < 0.5, 'centre restored');
  // The same pixels on screen (controls and navigator included).
  const shot2 = decodePng(await again.page.locator('#osd').screenshot());
  if (process.env.VTEX_SHOT_DIR) {
    await page.locator('#osd').screenshot({ path: `${process.env.VTEX_SHOT_DIR}/permalink-a.png` });
    await again.page.locator('#osd').screenshot({ path: `${process.env.VTEX_SHOT_DIR}/permalink-b.png` });
  }
  let differing = 0;
  for (let i = 0; i < shot.data.length; i += 4) if (Math.abs(shot.data[i] - shot2.data[i]) > 8) differing++;
  assert.ok(differing / (shot.width * shot.height) < 0.01, `screens match (${differing} pixels differ)`);
  assertClean(log);
  assertClean(again.log);
  await page.close();
  await again.page.close();
});

test('animated textures play through frames', async (t) => {
  const anim = textures.find((i) => i.animated);
  if (!anim) {
    t.skip('the server has no animated texture');
    return;
  }
  const { page, log } = await openViewer(browser.context, `${server.url}/?texture=${anim.id}&frame=2`);
  await waitForIdle(page);
  assert.equal(await page.evaluate(() => window.vtexViewer.state.frame), 2);
  assert.ok(tileRequests(log.requests).every((r) => r.id !== anim.id || r.frame === '2'), 'frame 2 requested');
  // Frame 2 on screen equals the server's frame-2 tile.
  // A level at least 1024 px wide (or level 0), drawn at 1:1 around its middle.
  let level = 0;
  while (level + 1 < anim.levels && Math.ceil(anim.width / 2 ** (level + 1)) >= 1024) level++;
  const s = 2 ** level;
  const lx = Math.floor(Math.ceil(anim.width / s) / 2 / anim.tile_size) * anim.tile_size + 16;
  const ly = Math.floor(Math.ceil(anim.height / s) / 2 / anim.tile_size) * anim.tile_size + 16;
  await setAlignedView(page, 1 / s, lx * s, ly * s);
  assert.equal(await compareScreenToTile(page, anim, level, lx, ly, 32, 2), 0, 'frame-2 pixels exact');
  await page.click('#play');
  await page.waitForFunction(() => window.vtexViewer.state.frame >= 5 || window.vtexViewer.state.frame < 2, null, { timeout: 30_000 });
  await page.click('#play');
  await waitForIdle(page);
  const frames = new Set(tileRequests(log.requests).filter((r) => r.id === anim.id).map((r) => r.frame));
  assert.ok(frames.size >= 3, `several frames requested: ${[...frames]}`);
  await page.waitForFunction(() => /frame=\d+/.test(location.search));
  assertClean(log);
  await page.close();
});
