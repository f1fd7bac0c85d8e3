// The golden files of wire/fixtures, written by the server's tests (server/tests/api/batch.rs):
// the viewer's batch reader must read the server's bytes as the server lists them, however the
// stream is cut into chunks, and the pyramid arithmetic must agree with the texture info.
import test from 'node:test';
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import { FrameReader } from '../src/shared/batch.js';
import { tileCount } from '../src/viewer/pyramid.js';

const fixture = (name) => readFileSync(new URL(`../../wire/fixtures/${name}`, import.meta.url));
const body = new Uint8Array(fixture('batch.bin'));
const want = JSON.parse(fixture('batch.json'));
const info = JSON.parse(fixture('texture-info.json'));

/** The frames `body` holds when pushed in chunks of `sizes` (cycled), with or without reuse. */
function read(sizes, reuse) {
  const got = [];
  const reader = new FrameReader((f) => got.push({ ...f, body: f.body.slice() }), { reuse });
  for (let at = 0, k = 0; at < body.length; k++) {
    const n = sizes[k % sizes.length];
    reader.push(body.subarray(at, at + n));
    at += n;
  }
  assert.ok(reader.complete, 'the stream ends between frames');
  return got;
}

for (const [name, sizes] of [['whole', [body.length]], ['byte by byte', [1]], ['uneven', [7, 33, 1000, 5]]]) {
  for (const reuse of [false, true]) {
    test(`the golden batch reads as the server lists it (${name}${reuse ? ', reusing a buffer' : ''})`, () => {
      const got = read(sizes, reuse);
      assert.equal(got.length, want.length);
      got.forEach((f, i) => {
        const w = want[i];
        const cache = { 1: 'hit', 2: 'miss', 0: null }[w.cache];
        assert.deepEqual(
          [f.level, f.x, f.y, f.status, f.cache, f.width, f.height, f.length],
          [w.level, w.x, w.y, w.status, cache, w.width, w.height, w.body_length],
        );
        assert.deepEqual(f.body, body.slice(w.body_offset, w.body_offset + w.body_length));
      });
    });
  }
}

test('a golden batch cut inside a frame is not complete', () => {
  const reader = new FrameReader(() => {});
  reader.push(body.subarray(0, body.length - 1));
  assert.equal(reader.complete, false);
});

test('the golden texture info has what the viewer reads, and its pyramid', () => {
  for (const k of ['id', 'width', 'height', 'levels', 'tile_size', 'domain', 'wraps', 'animated']) {
    assert.ok(k in info, `texture info has ${k}`);
  }
  assert.deepEqual(tileCount(info, 0), { x: info.width / info.tile_size, y: info.height / info.tile_size });
});
