// Unit tests of the viewer's pure modules (no browser): pyramid mapping, view URLs, statistics,
// tile scheduling (against a stand-in for OpenSeadragon's loader and world).
import test from 'node:test';
import assert from 'node:assert/strict';
import { inPyramid, levelSize, osdLevel, tileCount, tileUrl, vtexLevel, drawLevel } from '../src/pyramid.js';
import { formatView, parseView } from '../src/view-url.js';
import { TileStats, formatBytes, formatRatio, percentile } from '../src/stats.js';
import { PREVIEW_STEPS, scheduleTiles, wantedLevel } from '../src/loader.js';

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

test('drawLevel picks the level drawn at 1:1 or minified, never magnified', () => {
  assert.equal(drawLevel(big, 1), 0);
  assert.equal(drawLevel(big, 4), 0);
  assert.equal(drawLevel(big, 0.99), 0);
  assert.equal(drawLevel(big, 0.5), 1);
  assert.equal(drawLevel(big, 1 / 8), 3);
  assert.equal(drawLevel(big, 0.3), 1);
  assert.equal(drawLevel(big, 1e-9), 9);
  for (let z = 0.002; z < 1; z *= 1.07) {
    const ratio = z * 2 ** drawLevel(big, z);
    assert.ok(ratio >= 0.5 && ratio < 1.02, `zoom ${z}: tile pixels drawn at ${ratio}`);
  }
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
    },
  };
  return { viewer, loader, started, aborted, cleared: () => cleared, handlers };
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
