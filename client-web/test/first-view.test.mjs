// What the viewer opens (client-web/src/viewer/first-view.js) and the tiles a wrapping view shows
// (client-web/src/viewer/pyramid.js sourceTile).
import test from 'node:test';
import assert from 'node:assert/strict';
import { FIRST_ZOOM, SHOWCASE, firstView, openingView } from '../src/viewer/first-view.js';
import { sourceTile, osdLevel, tileCount } from '../src/viewer/pyramid.js';

const info = (id, name, width, height, wraps = false) => ({ id: id.repeat(64), name, width, height, levels: 10, tile_size: 256, wraps });
const huge = info('a', 'Huge cascade', 1_048_576, 1_048_576);
const showcase = info('b', SHOWCASE, 100_000, 100_000, true);
const small = info('c', 'Small', 4096, 4096, true);

test('without a link the showcase opens at its centre, zoomed in where its structure shows', () => {
  const { info: opened, view, message } = firstView([huge, showcase, small], {});
  assert.equal(opened, showcase);
  assert.deepEqual(view, { zoom: FIRST_ZOOM, x: 50_000, y: 50_000, texture: showcase.id });
  assert.equal(message, '');
});

test('without the showcase the largest texture opens, zoomed in; a view in the link is kept', () => {
  assert.equal(firstView([small, huge], {}).info, huge);
  assert.deepEqual(firstView([small, huge], {}).view, { zoom: FIRST_ZOOM, x: 524_288, y: 524_288, texture: huge.id });
  assert.deepEqual(firstView([small, huge], { zoom: 2, x: 5, y: 6 }).view, { zoom: 2, x: 5, y: 6, texture: huge.id });
});

test('a link naming a texture opens it at the link view, else where its structure shows; naming none says which is shown', () => {
  const linked = { texture: 'Small', zoom: 2, x: 5, y: 6, frame: 1 };
  assert.deepEqual(firstView([huge, small], linked), { info: small, view: { ...linked, texture: small.id }, message: '' });
  const named = firstView([huge, small], { texture: 'Small', frame: 1 });
  assert.deepEqual(named, { info: small, view: { texture: small.id, zoom: FIRST_ZOOM, x: 2048, y: 2048, frame: 1 }, message: '' });
  const bad = firstView([small, showcase, huge], { texture: 'nope', frame: 3 });
  assert.equal(bad.info, showcase);
  assert.equal(bad.view.texture, showcase.id);
  assert.equal(bad.view.frame, 3);
  assert.equal(bad.message, `No texture "nope" on this server (or more than one starts so); showing ${SHOWCASE}.`);
});

test('a picked texture opens as the first one does: at its centre at FIRST_ZOOM, or whole when it fits larger', () => {
  assert.deepEqual(openingView(huge, {}, 0.001), { zoom: FIRST_ZOOM, x: 524_288, y: 524_288, texture: huge.id });
  // 4096² in a 1000-pixel view fits at 0.24: half resolution shows more of it.
  assert.deepEqual(openingView(small, {}, 1000 / 4096), { zoom: FIRST_ZOOM, x: 2048, y: 2048, texture: small.id });
  // A texture smaller than the view is shown whole, magnified as OpenSeadragon's home shows it.
  const tiny = info('d', 'Tiny', 300, 200);
  assert.deepEqual(openingView(tiny, {}, 3), { zoom: 3, x: 150, y: 100, texture: tiny.id });
  // What the link or the caller fixes is kept.
  assert.deepEqual(openingView(huge, { zoom: 2, x: 1, y: 2 }, 0.001), { zoom: 2, x: 1, y: 2, texture: huge.id });
  // The same as the first view: firstView opens with openingView and the fit it is given.
  assert.deepEqual(firstView([tiny], {}, () => 3).view, openingView(tiny, {}, 3));
});

test('past the edges of a torus, tiles wrap modulo the grid of their level', () => {
  for (const level of [0, 2, 6, 9]) {
    const n = tileCount(showcase, level);
    const at = (x, y) => sourceTile(showcase, { level: osdLevel(showcase, level), x, y });
    assert.deepEqual(at(-1, -1), { level, x: n.x - 1, y: n.y - 1 });
    assert.deepEqual(at(n.x, 2 * n.y + 1), { level, x: 0, y: 1 % n.y });
    assert.deepEqual(at(3 % n.x, 0), { level, x: 3 % n.x, y: 0 });
  }
  // A plane's tiles are its own: nothing past its edges is asked for (tileExists).
  assert.deepEqual(sourceTile(huge, { level: osdLevel(huge, 0), x: -1, y: 5000 }), { level: 0, x: -1, y: 5000 });
});
