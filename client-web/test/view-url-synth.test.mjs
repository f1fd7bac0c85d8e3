// The client mode in the view's URL (src/viewer/view-url.js): `synth=client` is read, kept by links,
// and anything else is ignored (server mode).
import test from 'node:test';
import assert from 'node:assert/strict';
import { formatView, parseView } from '../src/viewer/view-url.js';

test('synth=client survives a link; other values mean server mode', () => {
  const view = parseView('?texture=t&zoom=0.5&x=10&y=20&synth=client');
  assert.equal(view.synth, 'client');
  assert.deepEqual(parseView(formatView(view)), view);
  assert.equal(parseView('?synth=server').synth, undefined);
  assert.equal(parseView('?synth=CLIENT').synth, undefined);
  assert.ok(!formatView({ texture: 't', zoom: 1, x: 0, y: 0 }).includes('synth'));
});
