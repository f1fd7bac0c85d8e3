// Virtual texturing's bookkeeping (client-web/src/shared/vt-pages.js) and KTX2 reading
// (client-web/src/shared/ktx2.js).
import test from 'node:test';
import assert from 'node:assert/strict';
import { METATILE_PAGES, PageCache, ancestor, decodeFeedback, fetchPlan, metatileOf, pageKey, plan, pyramid } from '../src/shared/vt-pages.js';
import { parseKtx2 } from '../src/shared/ktx2.js';

test('the page pyramid of a 100k texture: a 1024² table, level 10 one page', () => {
  const p = pyramid({ width: 100_000, height: 100_000 });
  assert.equal(p.tableSide, 1024);
  assert.equal(p.maxLevel, 10);
  assert.deepEqual(p.grid(0), [782, 782]);
  assert.deepEqual(p.grid(2), [196, 196], 'level 2 is 25,000 wide: 196 pages, more than 782 / 4');
  assert.deepEqual(p.grid(10), [1, 1]);
  for (let l = 0; l <= p.maxLevel; l++) assert.ok(p.grid(l)[0] <= p.tableSide >> l, `level ${l} fits its table mip`);
  assert.equal(pyramid({ width: 64, height: 64 }).maxLevel, 0);
  assert.throws(() => pyramid({ width: 1 << 20, height: 10 }), /needs more than 4096/);
});

test('pages of 128 come in metatiles of 4 × 4, the server’s 512 level pixels', () => {
  assert.equal(METATILE_PAGES, 4);
  assert.deepEqual(metatileOf(3, 5, 9), { key: '3/1/2', level: 3, x: 1, y: 2 });
  assert.deepEqual(metatileOf(0, 781, 3), { key: '0/195/0', level: 0, x: 195, y: 0 });
});

test('a metatile is fetched where at least half of one is wanted, or on its way; other pages alone', () => {
  const page = (level, x, y) => ({ key: pageKey(level, x, y), level, x, y });
  const block = (level, x0, y0, n) => Array.from({ length: n }, (_, i) => page(level, x0 + (i % 4), y0 + Math.floor(i / 4)));
  const shape = (plan) => plan.map((f) => (f.metatile ? `metatile ${f.metatile.key} ×${f.pages.length}` : `page ${f.pages[0].key}`));
  // 8 of 16 pages: the metatile; 7 of 16: page by page, in the order asked.
  assert.deepEqual(shape(fetchPlan([...block(0, 8, 8, 8), ...block(0, 0, 0, 7)], () => false)), [
    'metatile 0/2/2 ×8',
    ...block(0, 0, 0, 7).map((p) => `page ${p.key}`),
  ]);
  // The same 7 join their metatile when it is on its way.
  assert.deepEqual(shape(fetchPlan(block(0, 0, 0, 7), (k) => k === '0/0/0')), ['metatile 0/0/0 ×7']);
});

test('ancestors and feedback decoding', () => {
  assert.deepEqual(ancestor(0, 781, 5, 3), [97, 0]);
  const px = new Uint8Array([
    0x0e, 0x03, 0x21, 1, // level 0, x = 0x10e, y = 0x203
    0x0e, 0x03, 0x21, 1, // the same page again
    5, 6, 0, 4, // level 3, (5, 6)
    9, 9, 9, 0, // no surface
    7, 8, 0, 0x23, // texture 2, level 2, (7, 8)
  ]);
  const [pages, none, third] = decodeFeedback(px, 3);
  assert.deepEqual([...pages.keys()], ['0/270/515', '3/5/6']);
  assert.equal(pages.get('0/270/515').count, 2);
  assert.equal(none.size, 0);
  assert.deepEqual([...third.keys()], ['2/7/8']);
  assert.throws(() => decodeFeedback(px, 2), /texture 2 of 2/);
});

test('the cache evicts the least recently used unpinned page, never one used this frame', () => {
  const c = new PageCache(3);
  const page = (l, x, y) => ({ key: pageKey(l, x, y), level: l, x, y });
  assert.equal(c.insert(page(2, 0, 0), 0, true).evicted, null);
  c.insert(page(0, 1, 1), 1);
  c.insert(page(0, 2, 2), 2);
  assert.equal(c.available(3), 2);
  c.touch('0/1/1', 3);
  const r = c.insert(page(0, 3, 3), 3);
  assert.equal(r.evicted.key, '0/2/2', 'the least recently used');
  assert.ok(!c.has('0/2/2') && c.has('0/3/3') && c.has('2/0/0'));
  assert.equal(c.insert(page(0, 4, 4), 3), null, 'every other page is pinned or used in frame 3');
  // Using a fine page keeps its resident ancestors too.
  const [needed] = decodeFeedback(new Uint8Array([3, 3, 0, 1]));
  c.insert(page(1, 1, 1), 4);
  assert.equal(c.use(needed, 5, 2), 0);
  assert.equal(c.available(5), 0, '0/3/3, its ancestor 1/1/1 and the pinned 2/0/0 are all in use');
});

test('the plan asks for missing pages and their ancestors, coarsest first', () => {
  const [needed] = decodeFeedback(new Uint8Array([4, 4, 0, 1, 5, 4, 0, 1, 5, 4, 0, 1]));
  const resident = new Set(['2/1/1']);
  const inFlight = new Set(['1/2/2']);
  const keys = plan(needed, (k) => resident.has(k), (k) => inFlight.has(k), 3).map((p) => p.key);
  assert.deepEqual(keys, ['3/0/0', '0/5/4', '0/4/4']);
});

test('KTX2: level index read, supercompression refused', () => {
  const body = new Uint8Array(80 + 24 + 16);
  body.set([0xab, 0x4b, 0x54, 0x58, 0x20, 0x32, 0x30, 0xbb, 0x0d, 0x0a, 0x1a, 0x0a]);
  const v = new DataView(body.buffer);
  v.setUint32(12, 146, true);
  v.setUint32(20, 4, true);
  v.setUint32(24, 4, true);
  v.setUint32(40, 1, true);
  v.setBigUint64(80, 104n, true);
  v.setBigUint64(88, 16n, true);
  body.fill(7, 104);
  const k = parseKtx2(body);
  assert.equal(k.vkFormat, 146);
  assert.deepEqual([...k.data(0)], new Array(16).fill(7));
  v.setUint32(44, 2, true);
  assert.throws(() => parseKtx2(body), /supercompression/);
  v.setUint32(44, 0, true);
  v.setBigUint64(88, 17n, true);
  assert.throws(() => parseKtx2(body), /past the end/);
  assert.throws(() => parseKtx2(new Uint8Array(100)), /not a KTX2/);
});
