// Paint holding (src/hold.js) against a stand-in for OpenSeadragon's viewer, in Node.
import test from 'node:test';
import assert from 'node:assert/strict';
import { HOLD_MS, holdPaint } from '../src/hold.js';

/** A viewer with one tiled image, a drawer that records its frames and a settable clock. */
function fakeViewer() {
  const handlers = {};
  const on = (name, f) => (handlers[name] ||= []).push(f);
  const item = { opacity: 1, loaded: true, getFullyLoaded: () => item.loaded };
  const items = [item];
  const drawn = [];
  let redraws = 0;
  const clock = { t: 1000 };
  const viewer = {
    addHandler: on,
    world: { getItemCount: () => items.length, getItemAt: (i) => items[i], addHandler: on },
    drawer: { draw: (list) => drawn.push(list.map((i) => i.loaded)) },
    forceRedraw: () => redraws++,
  };
  const raise = (name, event = {}) => (handlers[name] || []).forEach((f) => f(event));
  /** setView(view, true): a zoom and a pan in one task. */
  const jump = () => {
    raise('zoom', { immediately: true });
    raise('pan', { immediately: true });
  };
  /** What OpenSeadragon does in a frame that needs a draw. */
  const frame = () => viewer.drawer.draw(items);
  const nextTask = () => new Promise((resolve) => setTimeout(resolve, 0));
  return { viewer, item, items, drawn, redraws: () => redraws, clock, raise, jump, frame, nextTask };
}

test('a complete view stays on the canvas until the new view is complete', async () => {
  const f = fakeViewer();
  const hold = holdPaint(f.viewer, { now: () => f.clock.t });
  assert.equal(hold.ms, HOLD_MS);
  f.jump();
  await f.nextTask();
  f.item.loaded = false; // the new view, evaluated: its tiles are on their way
  f.frame();
  f.clock.t += 16;
  f.frame(); // some tiles arrived
  assert.deepEqual(f.drawn, [], 'no stand-in frame');
  f.item.loaded = true;
  f.clock.t += 5;
  f.frame();
  assert.deepEqual(f.drawn, [[true]], 'the complete view, in one frame');
  assert.deepEqual({ holds: hold.holds, held: hold.held, expired: hold.expired }, { holds: 1, held: 2, expired: 0 });
  f.item.loaded = false;
  f.frame();
  assert.equal(f.drawn.length, 2, 'after the hold every frame is drawn');
});

test('at the deadline the view is drawn as it is, stand-ins and all', async () => {
  const f = fakeViewer();
  const hold = holdPaint(f.viewer, { ms: 5, now: () => performance.now() });
  f.jump();
  await f.nextTask();
  f.item.loaded = false;
  f.frame();
  assert.deepEqual(f.drawn, []);
  await new Promise((resolve) => setTimeout(resolve, 20));
  assert.equal(f.redraws(), 1, 'the deadline asks OpenSeadragon for a frame');
  f.frame();
  assert.deepEqual(f.drawn, [[false]]);
  assert.equal(hold.expired, 1);
});

test('a gesture, an animation or a view that was not complete is not held', async () => {
  const f = fakeViewer();
  const hold = holdPaint(f.viewer, { now: () => f.clock.t });
  // A drag step by step: the first step is held for a frame, the next one ends the hold.
  f.raise('pan', { immediately: true });
  await f.nextTask();
  f.item.loaded = false;
  f.frame();
  assert.equal(f.drawn.length, 0);
  f.raise('pan', { immediately: true });
  f.frame();
  assert.equal(f.drawn.length, 1, 'the next step of the gesture is drawn at once');
  // The view on the canvas is incomplete now: a change made at once starts no hold.
  await f.nextTask();
  f.jump();
  f.frame();
  assert.equal(f.drawn.length, 2);
  // An animated change is drawn frame by frame.
  f.item.loaded = true;
  f.raise('zoom', { immediately: false });
  f.item.loaded = false;
  f.frame();
  assert.equal(f.drawn.length, 3);
  // Switched off.
  f.item.loaded = true;
  hold.ms = 0;
  f.jump();
  f.item.loaded = false;
  f.frame();
  assert.equal(f.drawn.length, 4);
  assert.equal(hold.holds, 1);
});

test('a tiled image added or removed ends the hold; an invisible one does not count', async () => {
  const f = fakeViewer();
  const hold = holdPaint(f.viewer, { now: () => f.clock.t });
  // An animation frame loading behind the visible one (opacity 0) does not make it incomplete.
  f.items.push({ opacity: 0, getFullyLoaded: () => false });
  f.jump();
  assert.equal(hold.holds, 1);
  await f.nextTask();
  f.item.loaded = false;
  f.frame();
  assert.equal(f.drawn.length, 0);
  f.raise('add-item');
  f.frame();
  assert.equal(f.drawn.length, 1);
});
