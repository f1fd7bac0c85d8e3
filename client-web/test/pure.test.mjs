// Unit tests of the viewer's pure modules (no browser): pyramid mapping, view URLs, statistics,
// tile scheduling (against a stand-in for OpenSeadragon's loader and world).
import test from 'node:test';
import assert from 'node:assert/strict';
import { DETAIL, inPyramid, levelSize, osdLevel, tileCount, tileUrl, vtexLevel, drawLevel } from '../src/pyramid.js';
import { formatView, parseView } from '../src/view-url.js';
import { TileStats, formatBytes, formatRatio, percentile } from '../src/stats.js';
import { PREVIEW_STEPS, scheduleTiles, wantedLevel } from '../src/loader.js';
import { drawIncrementally, tilesToAdd, viewKey } from '../src/drawing.js';
import { addClips, hiddenTiles, pixelSpan, tileBoxes } from '../src/occlusion.js';
import { FrameReader, HEADER_LEN, MAGIC, MAX_BATCH, READ_BUFFER_BYTES, batchUrl, readChunks, tileKey } from '../src/batch.js';

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
  assert.equal(tileUrl(big, 3, 1, 2), `/api/v1/textures/${big.id}/tiles/3/1/2.png`);
  assert.equal(tileUrl(odd, 0, 2, 1, 7), `/api/v1/textures/${odd.id}/tiles/0/2/1.png?frame=7`);
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

/** A stand-in for OpenSeadragon's viewer: a loader with a queue, a world whose update adds jobs. */
function fakeViewer(jobsPerUpdate) {
  const started = [];
  const aborted = [];
  let cleared = 0;
  const handlers = {};
  const loader = {
    jobQueue: [],
    addJob(o) {
      started.push(o.src);
    },
    clear() {
      cleared++;
      this.jobQueue = [];
    },
  };
  let n = 0;
  const items = [];
  const worldHandlers = {};
  const viewer = {
    imageLoader: loader,
    addHandler: (name, f) => (handlers[name] = f),
    world: {
      update() {
        for (const [src, level] of jobsPerUpdate[n++] || []) {
          loader.addJob({ src, tile: { level }, abort: () => aborted.push(src) });
        }
        return true;
      },
      getItemCount: () => items.length,
      getItemAt: (i) => items[i],
      addHandler: (name, f) => (worldHandlers[name] = f),
    },
  };
  return { viewer, loader, started, aborted, cleared: () => cleared, handlers, items, worldHandlers };
}

test('scheduling keeps the queue until the next update and drops unwanted coarse levels', () => {
  const f = fakeViewer([
    [
      ['top', 0],
      ['mid', 5],
      ['preview', 6],
      ['coarse', 8],
      ['a', 9],
      ['b', 9],
    ],
    [['c', 9]],
  ]);
  scheduleTiles(f.viewer);
  // OpenSeadragon empties the queue after each draw: now that waits for the next update.
  f.loader.clear();
  assert.equal(f.cleared(), 0);
  f.viewer.world.update(true);
  assert.equal(f.cleared(), 1, 'an update starts from an empty queue');
  assert.deepEqual(f.started, ['top', 'preview', 'a', 'b'], "OpenSeadragon's order, unwanted levels left out");
  assert.deepEqual(f.aborted, ['mid', 'coarse'], 'dropped tiles are marked as not loading');
  f.viewer.world.update(true);
  assert.deepEqual(f.started.at(-1), 'c');
  f.handlers.close();
  assert.equal(f.cleared(), 3, 'closing empties the queue at once');
});

test('a view set at once is evaluated in the same task, at most once a frame', async () => {
  const f = fakeViewer([[['a', 9]], [['b', 9]], [['c', 9]]]);
  f.items.push({ source: {}, getTilesToDraw: () => [] });
  scheduleTiles(f.viewer);
  const frames = [];
  globalThis.requestAnimationFrame = (cb) => frames.push(cb);
  try {
    const tick = () => new Promise((resolve) => setTimeout(resolve, 0));
    f.handlers.pan({ immediately: false });
    await tick();
    assert.deepEqual(f.started, [], 'an animated change waits for the next frame');
    // setView: a zoom and a pan in one task make one early update.
    f.handlers.zoom({ immediately: true });
    f.handlers.pan({ immediately: true });
    assert.deepEqual(f.started, [], 'the update runs after the task that changed the view');
    await tick();
    assert.deepEqual(f.started, ['a']);
    f.handlers.pan({ immediately: true });
    await tick();
    assert.deepEqual(f.started, ['a'], 'no second early update before the next frame');
    frames.splice(0).forEach((cb) => cb());
    f.handlers.pan({ immediately: true });
    await tick();
    assert.deepEqual(f.started, ['a', 'b'], 'a frame later, one more');
  } finally {
    delete globalThis.requestAnimationFrame;
  }
});

/** A started job as OpenSeadragon's ImageJob has it after start(): abort wrapped, a timeout set. */
function startedJob(name, lastTouchTime, log, inFlight, x = 0) {
  const job = {
    name,
    tile: { level: 3, x, y: 0, lastTouchTime },
    jobId: 0,
    abort: () => {
      inFlight.delete(job); // the tile source's downloadTileAbort
      log.push(name);
    },
  };
  inFlight.add(job);
  return job;
}

test('started tiles the view no longer touches are aborted after an update that evaluated it', () => {
  const f = fakeViewer([[], [], []]);
  scheduleTiles(f.viewer);
  const log = [];
  const old = Date.now() - 1000;
  const inFlight = new Set();
  const keep = startedJob('keep', old, log, inFlight, 0);
  const left = startedJob('left', old, log, inFlight, 1);
  // The navigator's tiled image shares the tile source, with tiles of its own.
  const nav = startedJob('navigator', old, log, inFlight, 0);
  let drawn = [];
  const tilesMatrix = { 3: { 0: { 0: keep.tile }, 1: { 0: left.tile } } };
  const item = { source: { vtexInFlight: inFlight }, getTilesToDraw: () => drawn, tilesMatrix };
  f.items.push(item);
  f.loader.jobsInProgress = 2;
  // An update that evaluated nothing (OSD skipped the item): nothing is stale.
  f.viewer.world.update(true);
  assert.deepEqual(log, []);
  // An update that drew tiles and touched `keep` only (OSD stamps every tile the view needs).
  drawn = [{ currentTime: Date.now() + 10 }];
  keep.tile.lastTouchTime = Date.now() + 10;
  f.viewer.world.update(true);
  assert.deepEqual(log, ['left'], "the tile the view left is aborted, not the navigator's");
  assert.equal(f.loader.jobsInProgress, 1);
  // Removing the tiled image aborts the rest.
  f.worldHandlers['remove-item']({ item });
  assert.deepEqual(log, ['left', 'keep']);
  assert.equal(f.loader.jobsInProgress, 0);
  assert.deepEqual([...inFlight], [nav], "the navigator's job is its own viewer's business");
});

test('batch URLs list level/x/y and send the frame only for animated textures', () => {
  const tiles = [{ level: 0, x: 285, y: 160 }, { level: 3, x: 1, y: 2 }];
  assert.equal(batchUrl(big, tiles, 5, 'rgba'), `/api/v1/textures/${big.id}/tiles?format=rgba&tiles=0/285/160,3/1/2`);
  assert.equal(batchUrl(odd, tiles, 7, 'png'), `/api/v1/textures/${odd.id}/tiles?format=png&tiles=0/285/160,3/1/2&frame=7`);
  assert.equal(tileKey(3, 1, 2), '3/1/2');
  assert.equal(MAX_BATCH, 256);
  // The longest list the viewer can send stays well inside the server's 8 KiB query bound.
  const worst = Array.from({ length: MAX_BATCH }, (_, i) => ({ level: 0, x: 390 - (i % 10), y: 390 - i }));
  assert.ok(batchUrl(big, worst).length < 8192);
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

test('only tiles at least as fine as every drawn tile are drawn on top; anything else redraws', () => {
  const whole = { level: 0 };
  const preview = { level: 5 };
  const a = { level: 8 };
  const b = { level: 8 };
  const c = { level: 8 };
  assert.deepEqual(tilesToAdd([], [whole, preview]), [whole, preview]);
  assert.deepEqual(tilesToAdd([whole, preview], [whole, preview, a, b]), [a, b], 'finest tiles over the preview');
  assert.deepEqual(tilesToAdd([whole, preview, a], [whole, preview, a, b, c]), [b, c]);
  assert.deepEqual(tilesToAdd([whole, a], [whole, a]), [], 'nothing new: nothing drawn');
  assert.equal(tilesToAdd([whole, a], [whole, preview, a]), null, 'a coarser tile after a finer one would cover it');
  assert.equal(tilesToAdd([whole, preview, a], [whole, a, b]), null, 'a tile no longer drawn must be painted over');
  // ... unless the tiles drawn after it hide it.
  const seen = [];
  const under = (set) => ({ hidden: (order) => (seen.push(order.map((t) => t.level)), new Set(set)) });
  assert.deepEqual(tilesToAdd([whole, preview, a], [a, b], under([whole, preview])), [b]);
  assert.deepEqual(seen, [[0, 5, 8, 8]], 'judged in the order drawn: the canvas, then the new tiles');
  assert.equal(tilesToAdd([whole, preview, a], [a, b], under([whole])), null, 'the preview still shows');
  assert.equal(tilesToAdd([whole, a], [whole, preview, a], under([whole, preview])), null, 'a coarser tile after a finer one');
  // The new tiles must be drawable so that old tiles listed after them stay on top.
  assert.equal(tilesToAdd([whole, b], [whole, a, b], { clip: () => false }), null);
  const asked = [];
  assert.deepEqual(tilesToAdd([whole, b], [whole, a, b], { clip: (add) => asked.push(add) > 0 }), [a]);
  assert.deepEqual(asked, [[a]]);
});

/** A stand-in OpenSeadragon viewer: one tiled image, a view, and a canvas drawer that logs. */
function standInViewer() {
  const log = [];
  const events = [];
  let bounds = { x: 0, y: 0, width: 1, height: 0.75 };
  const item = {
    opacity: 1,
    tiles: [],
    smoothTileEdgesMinZoom: 1.1,
    zoom: 0.5,
    getRotation: () => 0,
    viewportToImageZoom() {
      return this.zoom;
    },
    getTilesToDraw() {
      this._lastDrawn = this.tiles.map((tile) => ({ tile }));
      return this._lastDrawn;
    },
  };
  const viewer = {
    viewport: {
      getRotation: () => 0,
      getFlip: () => false,
      getZoom: () => 1,
      getBoundsNoRotate: () => bounds,
      getContainerSize: () => ({ x: 960, y: 760 }),
    },
    drawer: {
      _imageSmoothingEnabled: true,
      draw(items) {
        log.push(['full', ...items.flatMap((i) => (i.opacity ? i.getTilesToDraw().map((d) => d.tile.name) : []))]);
      },
      _drawTile(tile) {
        log.push(['add', tile.name]);
      },
    },
    raiseEvent: (name, e) => events.push([name, e.tile.name]),
    forceRedraw: () => log.push(['forced']),
  };
  return { viewer, item, log, events, pan: () => (bounds = { ...bounds, x: bounds.x + 0.1 }) };
}

test('a frame of the same view draws only the tiles that arrived; a moved view redraws all', () => {
  const { viewer, item, log, events, pan } = standInViewer();
  const counts = drawIncrementally(viewer);
  const t = (name, level) => ({ name, level });
  const whole = t('whole', 0);
  const a = t('a', 8);
  const b = t('b', 8);
  const draw = () => viewer.drawer.draw([item]);
  item.tiles = [whole];
  draw();
  item.tiles = [whole, a];
  draw();
  item.tiles = [whole, a, b];
  draw();
  assert.deepEqual(log, [['full', 'whole'], ['add', 'a'], ['add', 'b']]);
  assert.deepEqual(events, [['tile-drawn', 'a'], ['tile-drawn', 'b']]);
  assert.deepEqual([counts.full, counts.incremental], [1, 2]);
  pan();
  draw();
  assert.deepEqual(log.at(-1), ['full', 'whole', 'a', 'b'], 'the view moved');
  viewer.forceRedraw();
  draw();
  assert.deepEqual(log.slice(-2), [['forced'], ['full', 'whole', 'a', 'b']], 'a forced redraw is a full one');
  item.tiles = [whole, t('p', 5), a, b];
  draw();
  assert.deepEqual(log.at(-1), ['full', 'whole', 'p', 'a', 'b'], 'a coarser tile arrived');
  // Beyond smoothTileEdgesMinZoom OpenSeadragon draws through its sketch canvas: always full.
  item.zoom = 2;
  assert.equal(viewKey(viewer, [item]), null);
  item.tiles = [whole, t('p', 5), a, b, t('c', 8)];
  draw();
  assert.equal(log.at(-1)[0], 'full');
  item.zoom = 0.5;
  // Two visible images (or none): full frames.
  assert.equal(viewKey(viewer, [item, { ...item }]), null);
  assert.equal(viewKey(viewer, [{ ...item, opacity: 0 }]), null);
  assert.notEqual(viewKey(viewer, [item, { ...item, opacity: 0 }]), null, 'an invisible image (a frame loading behind) is not drawn');
});

/** A tile drawn at CSS px (x, y) with size (w, h), as OpenSeadragon positions it. */
const placed = (name, level, x, y, w, h, more = {}) => ({ name, level, position: { x, y }, size: { x: w, y: h }, loaded: true, ...more });
const names = (set) => [...set].map((t) => t.name).sort();

test('a tile covers the pixels it spans whole; without anti-aliasing, those whose centres it holds', () => {
  // Anti-aliased: [0.3, 2.7) touches pixels 0–2 and covers only pixel 1.
  assert.deepEqual(pixelSpan(0.3, 2.7, false), { touch: [0, 3], cover: [1, 2] });
  // Whole pixels, up to floating-point noise.
  assert.deepEqual(pixelSpan(2 - 1e-9, 5 + 1e-9, false), { touch: [2, 5], cover: [2, 5] });
  // Centres: 0.5, 1.5 and 2.5 lie inside [0.3, 2.7); a centre on an edge may go either way.
  assert.deepEqual(pixelSpan(0.3, 2.7, true), { touch: [0, 3], cover: [0, 3] });
  assert.deepEqual(pixelSpan(0.5, 2.5, true), { touch: [0, 3], cover: [1, 2] });
  const boxes = tileBoxes(placed('t', 1, -10.5, 4.25, 20, 10), { width: 8, height: 100 });
  assert.deepEqual(boxes, { touch: [0, 4, 8, 15], cover: [-10, 5, 9, 14], centres: false }, 'touch is clipped to the canvas');
  assert.equal(tileBoxes(placed('t', 1, 0, 0, 20, 10, { hasTransparency: true }), { width: 8, height: 8 }).cover, null, 'a transparent tile covers nothing');
  assert.equal(tileBoxes({ level: 1 }, { width: 8, height: 8 }), null, 'a tile without a place');
  // Less than a pixel wide, Chromium anti-aliases the image: it covers no pixel whole.
  assert.equal(tileBoxes(placed('sliver', 1, 10.2, 0, 0.9, 10), { width: 99, height: 99, centres: true }).cover, null);
  assert.deepEqual(tileBoxes(placed('thin', 1, 10.2, 0, 1.1, 10), { width: 99, height: 99, centres: true }).cover, [10, 0, 11, 10]);
  // An edge far from the tile's centre is only known to float32 precision: a centre within
  // 0.1 px of it counts as on it.
  const huge = tileBoxes(placed('huge', 0, -100_000, 0, 100_099.55, 10), { width: 200, height: 99, centres: true });
  assert.deepEqual([huge.touch[2], huge.cover[2]], [100, 99]);
  assert.deepEqual(tileBoxes(placed('small', 0, -100, 0, 199.55, 10), { width: 200, height: 99, centres: true }).cover[2], 100);
});

test('a tile is hidden only where opaque tiles drawn after it cover every pixel it touches', () => {
  const canvas = { width: 200, height: 100 };
  const whole = placed('whole', 0, -50.2, -30.7, 400.4, 300.3);
  // Four finer tiles over the canvas with whole-pixel edges.
  const grid = (dx = 0, gap = 0) => [
    placed('a', 5, -3, -3, 103 + dx, 53),
    placed('b', 5, 100 + dx + gap, -3, 103, 53),
    placed('c', 5, -3, 50, 103 + dx, 53),
    placed('d', 5, 100 + dx + gap, 50, 103, 53),
  ];
  assert.deepEqual(names(hiddenTiles([whole, ...grid()], canvas).hidden), ['whole']);
  assert.deepEqual(names(hiddenTiles([...grid(), whole], canvas).hidden), ['a', 'b', 'c', 'd'], 'what is drawn later covers what was drawn before');
  // Abutting at a fractional edge: the pixel column across x = 100.4 is split between a and b.
  // Anti-aliased, the coarse tile shows through it; by pixel centres it does not.
  assert.deepEqual(names(hiddenTiles([whole, ...grid(0.4)], canvas).hidden), []);
  assert.deepEqual(names(hiddenTiles([whole, ...grid(0.4)], { ...canvas, centres: true }).hidden), ['whole']);
  // Enlarged by a pixel (OpenSeadragon's overlap while smoothing): every pixel lies whole in one tile.
  const enlarged = grid(0.4).map((t, i) => (i % 2 === 0 ? { ...t, size: { x: t.size.x + 1, y: t.size.y } } : t));
  assert.deepEqual(names(hiddenTiles([whole, ...enlarged], canvas).hidden), ['whole']);
  // A gap between finer tiles, even a tenth of a pixel, keeps the coarse tile.
  assert.deepEqual(names(hiddenTiles([whole, ...grid(0, 0.1)], canvas).hidden), []);
  assert.deepEqual(names(hiddenTiles([whole, ...grid(0, 1)], { ...canvas, centres: true }).hidden), []);
  // A missing finer tile keeps the coarse one; a transparent one does not cover.
  assert.deepEqual(names(hiddenTiles([whole, ...grid().slice(1)], canvas).hidden), []);
  const glass = grid().map((t) => (t.name === 'c' ? { ...t, hasTransparency: true } : t));
  assert.deepEqual(names(hiddenTiles([whole, ...glass], canvas).hidden), []);
  // Only what lies on the canvas counts; a tile off the canvas is hidden.
  const left = grid().filter((t) => t.name === 'a' || t.name === 'c');
  const halfCanvas = { width: 100, height: 100 };
  assert.deepEqual(names(hiddenTiles([whole, ...left, placed('off', 5, 300, 0, 50, 50)], halfCanvas).hidden), ['off', 'whole']);
  // A mid-level tile partly under the finest tiles stays; the whole tile under both goes.
  const mid = placed('mid', 2, 50, -10, 300, 200);
  const r = hiddenTiles([whole, placed('left', 2, -20, -10, 71, 200), mid, ...grid().slice(0, 1)], canvas);
  assert.deepEqual(names(r.hidden), ['whole']);
  assert.equal(r.area, 200 * 100 + 51 * 100 + 150 * 100 + 100 * 50);
  assert.equal(r.hiddenArea, 200 * 100);
  assert.equal(r.trims.size, 0, 'mid: 50 × 50 pixels under a are too few to clip it for');
  // A partly hidden tile is drawn clipped to what shows of it when that spares at least a
  // quarter of it and 4096 pixels.
  const w = placed('w', 0, 0, 0, 200, 100);
  const trimmed = hiddenTiles([w, placed('x', 5, 0, 0, 80, 80)], canvas);
  assert.deepEqual([...trimmed.trims], [[w, [[0, 80, 200, 100], [80, 0, 200, 80]]]]);
  assert.equal(trimmed.trimmedArea, 80 * 80);
  assert.equal(hiddenTiles([w, placed('x', 5, 0, 0, 60, 60)], canvas).trims.size, 0, 'too little to spare');
});

test('a new tile listed before an old one it overlaps is drawn outside the pixels the old one overwrites', () => {
  const canvas = { width: 200, height: 100, centres: true };
  // One level, enlarged by a pixel: a (column 0) overlaps b (column 1) by a pixel column.
  const a = placed('a', 5, -3.3, -3.2, 104, 54);
  const b = placed('b', 5, 99.7, -3.2, 104, 54);
  const c = placed('c', 5, -3.3, 49.8, 104, 54);
  // b and c on the canvas, a arrives: next lists a before b and c, which a full redraw draws over it.
  const clips = addClips([b, c], [a], [a, b, c], canvas);
  assert.deepEqual(clips.get(a), [[0, 0, 100, 50]], 'a is drawn outside b (x ≥ 100) and c (y ≥ 50)');
  assert.equal(addClips([a], [b], [a, b], canvas).size, 0, 'listed after the old tile: drawn whole');
  assert.equal(addClips([b, c], [a], [a, b, c], { ...canvas, centres: false }), null, 'anti-aliased, the shared pixels blend');
  // b's edge on a pixel centre: which pixels it overwrites is not known.
  const bHalf = placed('b', 5, 99.5, -3.2, 104, 54);
  assert.equal(addClips([bHalf], [a], [a, bHalf], canvas), null);
  // Wholly under old tiles listed after it: drawn nowhere.
  const under = placed('under', 5, 110, 10, 20, 20);
  assert.deepEqual(addClips([b], [under], [under, b], canvas).get(under), []);
  // A clipped tile hides only where it is drawn.
  const whole = placed('whole', 0, -50, -30, 400, 300);
  const clipMap = new Map([[a, [[0, 0, 50, 50]]]]);
  assert.deepEqual(names(hiddenTiles([whole, placed('p', 2, 0, 0, 40, 40), a], canvas, clipMap).hidden), ['p']);
  assert.deepEqual(names(hiddenTiles([placed('q', 2, 45, 0, 10, 10), a], canvas, clipMap).hidden), [], 'q reaches x 55, where a is not drawn');
});

test('full and incremental frames leave out hidden tiles; without pruning every tile is drawn', () => {
  const { viewer, item, log, events } = standInViewer();
  viewer.drawer.canvas = { width: 200, height: 100 };
  const frames = drawIncrementally(viewer);
  const whole = placed('whole', 0, -50, -30, 400, 300);
  const p = placed('p', 2, -10, -10, 300, 200);
  const [a, b] = [placed('a', 5, -3, -3, 103, 106), placed('b', 5, 99, -3, 103, 106)];
  const draw = () => viewer.drawer.draw([item]);
  item.tiles = [whole, a];
  draw();
  item.tiles = [whole, p, a, b];
  draw(); // p is coarser than a: a full frame, in which p and whole are hidden
  assert.deepEqual(log, [['full', 'whole', 'a'], ['full', 'a', 'b']]);
  assert.deepEqual(item._lastDrawn.map((d) => d.tile.name), ['whole', 'p', 'a', 'b'], 'the frame still lists every tile');
  // Left out: whole and p here, and in the first frame the right half of whole (trimmed off: a hid its left half).
  assert.deepEqual([frames.hidden, frames.tiles, frames.hiddenPixels], [2, 4, 2 * 200 * 100 + 100 * 100]);
  // An incremental frame: of the tiles that arrived, the coarse one under the fine one is left out.
  const c = placed('c', 6, 12, 12, 5, 5);
  const d = placed('d', 7, 10, 10, 20, 20);
  item.tiles = [whole, p, a, b, c, d];
  draw();
  assert.deepEqual(log.at(-1), ['add', 'd']);
  assert.deepEqual(events.at(-1), ['tile-drawn', 'd']);
  assert.equal(log.filter((l) => l[0] === 'add').length, 1, 'only d was added: c lies under it');
  assert.deepEqual([frames.full, frames.incremental, frames.hidden], [2, 1, 3]);
  // Switching pruning off redraws in full, every tile.
  frames.prune = false;
  draw();
  assert.deepEqual(log.at(-1), ['full', 'whole', 'p', 'a', 'b', 'c', 'd']);
  frames.prune = true;
  draw();
  assert.deepEqual(log.at(-1), ['full', 'a', 'b', 'd']);
  // The finest level completes: OpenSeadragon drops the coarser tiles under it from the list,
  // and the frame only adds the new tile.
  const e = placed('e', 7, 30, 30, 20, 20);
  const hidden = frames.hidden;
  item.tiles = [a, b, c, d, e];
  draw();
  assert.deepEqual(log.at(-1), ['add', 'e']);
  assert.equal(frames.hidden, hidden + 2, 'whole and p were not drawn again');
  // A dropped tile that would still show makes a full frame.
  const [f, g] = [placed('f', 7, 0, 0, 10, 10), placed('g', 7, 0, 0, 10, 10)];
  item.tiles = [p, a, f];
  draw();
  item.tiles = [a, g];
  draw();
  assert.deepEqual(log.at(-1), ['full', 'a', 'g'], 'p showed right of a');
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
