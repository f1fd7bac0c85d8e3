// Unit tests of the viewer's pure modules (no browser): pyramid mapping, view URLs, statistics,
// the early view update (against a stand-in for OpenSeadragon's viewer), batch frames.
import test from 'node:test';
import assert from 'node:assert/strict';
import {
  DETAIL,
  drawLevel,
  inPyramid,
  levelSize,
  metatilesOf,
  metatileUrl,
  osdLevel,
  tileCount,
  tileUrl,
  vtexLevel,
} from '../src/viewer/pyramid.js';
import { formatView, parseView } from '../src/viewer/view-url.js';
import { TileStats, formatBytes, formatRatio, percentile } from '../src/viewer/stats.js';
import { updateEarly } from '../src/viewer/loader.js';
import { PREVIEW_STEPS, fetchWantedLevels, wantedLevel } from '../src/viewer/osd-adapter.js';
import { FrameReader, HEADER_LEN, MAGIC, READ_BUFFER_BYTES, readChunks, tileKey } from '../src/shared/batch.js';

const big = { id: 'ab'.repeat(32), width: 100_000, height: 100_000, levels: 10, tile_size: 256, animated: false };
const odd = { id: 'cd'.repeat(32), width: 3000, height: 700, levels: 5, tile_size: 256, animated: true };

test('OpenSeadragon levels count up from the smallest, vtex levels from full resolution', () => {
  assert.equal(vtexLevel(big, 9), 0);
  assert.equal(vtexLevel(big, 0), 9);
  for (let l = 0; l < big.levels; l++) assert.equal(vtexLevel(big, osdLevel(big, l)), l);
});

test('level sizes round up and the last served level fits one tile', () => {
  assert.deepEqual(levelSize(big, 0), { width: 100_000, height: 100_000 });
  assert.deepEqual(levelSize(big, 5), { width: 3125, height: 3125 });
  assert.deepEqual(levelSize(big, 6), { width: 1563, height: 1563 });
  assert.deepEqual(tileCount(big, 0), { x: 391, y: 391 });
  assert.deepEqual(tileCount(big, 9), { x: 1, y: 1 });
  assert.deepEqual(tileCount(odd, 0), { x: 12, y: 3 });
  assert.deepEqual(tileCount(odd, 4), { x: 1, y: 1 });
});

test('OpenSeadragon tile counts agree with the server pyramid at every level', () => {
  // OSD computes ceil(W * 2^(k - maxLevel) / tileSize) tiles at its level k.
  for (const info of [big, odd]) {
    for (let k = 0; k < info.levels; k++) {
      const scale = 1 / 2 ** (info.levels - 1 - k);
      const osd = { x: Math.ceil((info.width * scale) / info.tile_size), y: Math.ceil((info.height * scale) / info.tile_size) };
      assert.deepEqual(osd, tileCount(info, vtexLevel(info, k)), `level ${k}`);
    }
  }
});

test('nothing outside the pyramid has a URL', () => {
  assert.equal(inPyramid(big, 0, 390, 390), true);
  assert.equal(inPyramid(big, 0, 391, 0), false);
  assert.equal(inPyramid(big, 10, 0, 0), false);
  assert.equal(inPyramid(big, -1, 0, 0), false);
  assert.equal(inPyramid(big, 0, -1, 0), false);
  assert.equal(inPyramid(big, 0, 1.5, 0), false);
  assert.equal(inPyramid(odd, 0, 11, 2), true);
  assert.equal(inPyramid(odd, 0, 11, 3), false);
  assert.equal(tileUrl(big, 0, 391, 0), null);
  assert.equal(tileUrl(big, 3, 1, 2), `api/v1/textures/${big.id}/tiles/3/1/2.png`);
  assert.equal(tileUrl(odd, 0, 2, 1, 7), `api/v1/textures/${odd.id}/tiles/0/2/1.png?frame=7`);
});

test('drawLevel: `map` draws the level nearest the screen resolution, `sharp` never magnifies', () => {
  for (const detail of ['map', 'sharp']) {
    const at = (zoom) => drawLevel(big, zoom, DETAIL[detail]);
    // At exactly 1/2^L both draw level L at 1:1; deeper than 1:1, level 0.
    for (let l = 0; l < 10; l++) assert.equal(at(2 ** -l), l, `${detail} at 1/2^${l}`);
    assert.equal(at(4), 0);
    assert.equal(at(1e-9), 9);
  }
  assert.equal(drawLevel(big, 0.99, DETAIL.sharp), 0);
  assert.equal(drawLevel(big, 0.3, DETAIL.sharp), 1);
  assert.equal(drawLevel(big, 0.72), 0); // `map` is the default
  assert.equal(drawLevel(big, 0.7, DETAIL.map), 1);
  assert.equal(drawLevel(big, 0.3, DETAIL.map), 2);
  const range = (detail) => {
    let [lo, hi] = [Infinity, 0];
    for (let z = 0.002; z < 1; z *= 1.01) {
      const ratio = z * 2 ** drawLevel(big, z, DETAIL[detail]);
      [lo, hi] = [Math.min(lo, ratio), Math.max(hi, ratio)];
    }
    return [lo, hi];
  };
  const [mapLo, mapHi] = range('map');
  assert.ok(mapLo >= Math.SQRT1_2 && mapLo < 0.72 && mapHi < Math.SQRT2 && mapHi > 1.39, `map: ${mapLo}–${mapHi}`);
  const [sharpLo, sharpHi] = range('sharp');
  assert.ok(sharpLo >= 0.51 && sharpLo < 0.52 && sharpHi < 1.02 && sharpHi > 1.0, `sharp: ${sharpLo}–${sharpHi}`);
});

test('a view survives the URL round trip; malformed fields are dropped', () => {
  const view = { texture: big.id, zoom: 2.5, x: 73000.25, y: 41000, frame: 3 };
  assert.deepEqual(parseView(formatView(view)), { texture: big.id, zoom: 2.5, x: 73000.25, y: 41000, frame: 3 });
  assert.deepEqual(parseView('?texture=t&zoom=-1&x=1&y=nope&frame=1.5'), { texture: 't' });
  assert.deepEqual(parseView('?zoom=0.001&x=5&y=6'), { zoom: 0.001, x: 5, y: 6 });
  assert.deepEqual(parseView(''), {});
  assert.deepEqual(parseView('?format=rgba'), { format: 'rgba' });
  assert.deepEqual(parseView('?format=gif'), {});
  assert.equal(formatView({ texture: 't', format: 'webp' }), '?texture=t&format=webp');
  assert.deepEqual(parseView('?detail=sharp'), { detail: 'sharp' });
  assert.deepEqual(parseView('?detail=toString'), {});
  assert.equal(formatView({ texture: 't', detail: 'sharp' }), '?texture=t&detail=sharp');
  assert.equal(formatView({ zoom: 0.123456789012, x: 1.23456, y: 2 }), '?zoom=0.123456789&x=1.235&y=2');
  assert.equal(formatView({ texture: 'a b', zoom: 1, x: 1, y: 2, frame: 0 }), '?texture=a+b&zoom=1&x=1&y=2');
});

test('percentiles use the nearest rank', () => {
  const v = Array.from({ length: 100 }, (_, i) => 100 - i);
  assert.equal(percentile(v, 0.5), 50);
  assert.equal(percentile(v, 0.95), 95);
  assert.equal(percentile([7], 0.95), 7);
  assert.ok(Number.isNaN(percentile([], 0.5)));
});

test('tile statistics count server cache hits, browser cache and bytes', () => {
  const s = new TileStats(3);
  for (const [ms, cache] of [[10, 'miss'], [20, 'hit'], [30, 'hit'], [40, null]]) {
    s.started();
    s.loadedTile(ms, 100, cache);
  }
  s.resource({ transferSize: 0, decodedBodySize: 100 });
  s.resource({ transferSize: 400, decodedBodySize: 100 });
  const snap = s.snapshot();
  assert.equal(snap.requested, 4);
  assert.equal(snap.serverHits, 2);
  assert.equal(snap.serverMisses, 1);
  assert.equal(snap.browserCached, 1);
  assert.equal(snap.bodyBytes, 400);
  assert.equal(snap.wireBytes, 400);
  assert.equal(snap.p50, 30); // window of 3 keeps 20, 30, 40
});

test('byte counts and ratios read well', () => {
  assert.equal(formatBytes(999), '999 B');
  assert.equal(formatBytes(30_000_000_000), '30.0 GB');
  assert.equal(formatBytes(12_345), '12.3 kB');
  assert.equal(formatRatio(30_000_000_000, 12_345), '2,430,134 : 1');
  assert.equal(formatRatio(30, 4), '7.50 : 1');
  assert.equal(formatRatio(1, 0), '–');
});

test('only the finest level, one preview level and the whole-texture tile are fetched', () => {
  assert.equal(PREVIEW_STEPS, 3);
  assert.ok(wantedLevel(9, 9) && wantedLevel(6, 9) && wantedLevel(0, 9));
  for (const level of [8, 7, 5, 4, 1]) assert.ok(!wantedLevel(level, 9), `level ${level}`);
  assert.ok(wantedLevel(2, 2) && wantedLevel(0, 2) && !wantedLevel(1, 2));
});

test("the jobs of one task reach the loader in OpenSeadragon's order, unwanted levels given back", async () => {
  const added = [];
  const aborted = [];
  const viewer = { imageLoader: { addJob: (o) => added.push(o.src) } };
  fetchWantedLevels(viewer);
  const job = (src, level) => ({ src, tile: { level }, abort: () => aborted.push(src) });
  for (const [src, level] of [['top', 0], ['mid', 5], ['preview', 6], ['coarse', 8], ['a', 9], ['b', 9]]) {
    viewer.imageLoader.addJob(job(src, level));
  }
  assert.deepEqual(added, [], 'held until the task that added them is over');
  await Promise.resolve();
  assert.deepEqual(added, ['top', 'preview', 'a', 'b']);
  assert.deepEqual(aborted, ['mid', 'coarse'], 'dropped tiles are marked as not loading');
  // The next task's jobs are judged on their own: its finest level is 6.
  viewer.imageLoader.addJob(job('c', 6));
  viewer.imageLoader.addJob(job('d', 3));
  viewer.imageLoader.addJob(job('e', 5));
  await Promise.resolve();
  assert.deepEqual(added.slice(4), ['c', 'd']);
  assert.deepEqual(aborted.slice(2), ['e']);
});

/** A stand-in for OpenSeadragon's viewer: handlers by event, a world counting its updates. */
function fakeViewer() {
  const handlers = {};
  const world = { updates: 0, update: () => world.updates++, getItemCount: () => 1 };
  return { viewer: { world, addHandler: (name, f) => (handlers[name] = f) }, handlers, world };
}

test('a view set at once is evaluated in the same task, at most once a frame', async () => {
  const f = fakeViewer();
  updateEarly(f.viewer);
  const frames = [];
  globalThis.requestAnimationFrame = (cb) => frames.push(cb);
  try {
    const tick = () => new Promise((resolve) => setTimeout(resolve, 0));
    f.handlers.pan({ immediately: false });
    await tick();
    assert.equal(f.world.updates, 0, 'an animated change waits for the next frame');
    // setView: a zoom and a pan in one task make one early update.
    f.handlers.zoom({ immediately: true });
    f.handlers.pan({ immediately: true });
    assert.equal(f.world.updates, 0, 'the update runs after the task that changed the view');
    await tick();
    assert.equal(f.world.updates, 1);
    f.handlers.pan({ immediately: true });
    await tick();
    assert.equal(f.world.updates, 1, 'no second early update before the next frame');
    frames.splice(0).forEach((cb) => cb());
    f.handlers.pan({ immediately: true });
    await tick();
    assert.equal(f.world.updates, 2, 'a frame later, one more');
  } finally {
    delete globalThis.requestAnimationFrame;
  }
});

test('metatile URLs name the block and send the frame only for animated textures', () => {
  assert.equal(metatileUrl(big, 0, 142, 80, 5, 'jpg'), `api/v1/textures/${big.id}/metatiles/0/142/80.jpg`);
  assert.equal(metatileUrl(odd, 3, 0, 1, 7, 'png'), `api/v1/textures/${odd.id}/metatiles/3/0/1.png?frame=7`);
  assert.equal(tileKey(3, 1, 2), '3/1/2');
});

test('tiles group into the metatiles that hold them, coarsest level first', () => {
  const info = { ...big, metatile: 2 };
  const t = (level, x, y) => ({ level, x, y });
  const tiles = [t(0, 4, 6), t(0, 5, 7), t(0, 6, 6), t(3, 1, 1), t(0, 5, 6), t(3, 0, 0)];
  const blocks = metatilesOf(info, tiles);
  assert.deepEqual(
    blocks.map((b) => [b.level, b.x, b.y, b.tiles.length]),
    [
      [3, 0, 0, 2],
      [0, 2, 3, 3],
      [0, 3, 3, 1],
    ],
  );
  assert.deepEqual(blocks[1].tiles, [t(0, 4, 6), t(0, 5, 7), t(0, 5, 6)], 'each tile once, in the order given');
  assert.equal(metatilesOf({ ...big, metatile: 1 }, tiles).length, tiles.length, 'one tile a block');
});

test('batch frames are read whatever the chunk boundaries', () => {
  const frames = [
    { level: 0, x: 285, y: 160, status: 200, cache: 'miss', width: 2, height: 1, body: [1, 2, 3, 4, 5, 6, 7, 8] },
    { level: 3, x: 1, y: 2, status: 404, cache: null, width: 0, height: 0, body: [...new TextEncoder().encode('{"error":"no"}')] },
    { level: 9, x: 0, y: 0, status: 200, cache: 'hit', width: 1, height: 1, body: [9, 9, 9, 255] },
  ];
  const bytes = [];
  for (const f of frames) bytes.push(...encodeHeader({ ...f, length: f.body.length }), ...f.body);
  assert.equal(bytes.length, 3 * HEADER_LEN + 8 + 14 + 4);
  const all = Uint8Array.from(bytes);
  for (const size of [1, 3, 31, 32, 33, 40, all.length]) {
    const got = [];
    const reader = new FrameReader((f) => got.push({ ...f, body: [...f.body], length: undefined }));
    for (let i = 0; i < all.length; i += size) {
      reader.push(all.subarray(i, i + size));
    }
    assert.deepEqual(got, frames.map((f) => ({ ...f, length: undefined })), `chunks of ${size}`);
    assert.ok(reader.complete);
  }
  // With `reuse`, split frames share one buffer: each body is right while onFrame runs.
  for (const size of [1, 5, 33, all.length]) {
    const got = [];
    const bodies = new Set();
    const reader = new FrameReader(
      (f) => {
        got.push({ ...f, body: [...f.body], length: undefined });
        bodies.add(f.body.buffer);
      },
      { reuse: true },
    );
    for (let i = 0; i < all.length; i += size) reader.push(all.subarray(i, i + size));
    assert.deepEqual(got, frames.map((f) => ({ ...f, length: undefined })), `reused buffer, chunks of ${size}`);
    assert.ok(reader.complete);
    if (size < all.length) assert.equal(bodies.size, 2, 'split frames share one buffer (it grew once, for the 14-byte body)');
  }
  const cut = new FrameReader(() => {});
  cut.push(all.subarray(0, 36));
  assert.ok(!cut.complete, 'a stream cut inside a frame is noticed');
  const bad = Uint8Array.from(all);
  bad[3] = 2;
  assert.throws(() => new FrameReader(() => {}).push(bad), /not a vtex tile batch frame/);
});

test('a body is read through one reused buffer where the stream allows it, else chunk by chunk', async () => {
  const parts = [Uint8Array.of(1, 2, 3), Uint8Array.of(4), new Uint8Array(5000).fill(7)];
  const expected = [1, 2, 3, 4, ...new Array(5000).fill(7)];
  // A byte stream (as fetch bodies are in Chromium): chunks land in the pool's buffer.
  const bytes = () => {
    let i = 0;
    return new ReadableStream({
      type: 'bytes',
      pull(c) {
        if (i < parts.length) c.enqueue(Uint8Array.from(parts[i++]));
        else {
          c.close();
          if (c.byobRequest) c.byobRequest.respond(0); // a pending BYOB read ends with the stream
        }
      },
    });
  };
  const pool = [];
  const seen = [];
  const buffers = new Set();
  await readChunks(bytes(), (chunk) => {
    seen.push(...chunk);
    buffers.add(chunk.byteLength && chunk.buffer.byteLength);
  }, pool);
  assert.deepEqual(seen, expected);
  assert.deepEqual([...buffers], [READ_BUFFER_BYTES], 'every chunk is a view of the one buffer');
  assert.equal(pool.length, 1, 'the buffer went back to the pool');
  const again = [];
  await readChunks(bytes(), (chunk) => again.push(...chunk), pool);
  assert.deepEqual(again, expected);
  assert.equal(pool.length, 1, 'the second body reused it');
  // A plain stream: its chunks as they come.
  let j = 0;
  const plain = new ReadableStream({
    pull(c) {
      if (j < parts.length) c.enqueue(parts[j++]);
      else c.close();
    },
  });
  const got = [];
  await readChunks(plain, (chunk) => got.push(chunk), []);
  assert.deepEqual(got, parts);
  // An error in the stream reaches the caller.
  const broken = new ReadableStream({
    type: 'bytes',
    pull(c) {
      c.error(new Error('cut'));
    },
  });
  await assert.rejects(readChunks(broken, () => {}, []), /cut/);
});
/** A frame header as the server writes it (server/src/api/batch.rs): what FrameReader parses. */
function encodeHeader({ level, x, y, status = 200, cache = 'hit', width, height, length }) {
  const h = new Uint8Array(HEADER_LEN);
  h.set(MAGIC);
  const v = new DataView(h.buffer);
  v.setUint32(4, level, true);
  v.setUint32(8, x, true);
  v.setUint32(12, y, true);
  v.setUint16(16, status, true);
  h[18] = cache === 'hit' ? 1 : cache === 'miss' ? 2 : 0;
  v.setUint32(20, width, true);
  v.setUint32(24, height, true);
  v.setUint32(28, length, true);
  return h;
}
