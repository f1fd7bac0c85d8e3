// The 3D world's scene (client-web/src/world/scene.js): the walls' texture runs on round the
// corners, the board shows its whole texture undistorted, the walk stays inside the courtyard.
import test from 'node:test';
import assert from 'node:assert/strict';
import { CENTRE, EYE, HALF, rectangles, walk } from '../src/world/scene.js';

const sizes = { board: { width: 12288, height: 1536 }, walls: { width: 100_000, height: 100_000 } };
const length = (a, b) => Math.hypot(...a.map((v, i) => v - b[i]));

test('the walls close round the courtyard, their texture continuous at every corner and 1 texel a unit', () => {
  const walls = rectangles(sizes).filter((r) => r.role === 'walls');
  assert.equal(walls.length, 4);
  walls.forEach((w, i) => {
    const next = walls[(i + 1) % 4];
    assert.deepEqual(w.corners[1], next.corners[0], `wall ${i} ends where wall ${i + 1} starts`);
    if (i < 3) assert.deepEqual(w.texels[1], next.texels[0], `texels run on from wall ${i} to wall ${i + 1}`);
    assert.equal(length(w.corners[0], w.corners[1]), length(w.texels[0], w.texels[1]));
    assert.equal(length(w.corners[1], w.corners[2]), length(w.texels[1], w.texels[2]));
    assert.ok(w.texels[0][1] > w.texels[3][1], 'texture rows run top down');
  });
});

test('the board shows its whole texture, at one scale both ways, in front of the north wall', () => {
  const [board] = rectangles(sizes).filter((r) => r.role === 'board');
  assert.deepEqual(board.texels, [[0, 1536], [12288, 1536], [12288, 0], [0, 0]]);
  const scale = length(board.texels[0], board.texels[1]) / length(board.corners[0], board.corners[1]);
  assert.ok(Math.abs(scale - length(board.texels[1], board.texels[2]) / length(board.corners[1], board.corners[2])) < 1e-9);
  for (const [x, y] of board.corners) {
    assert.ok(Math.abs(x - CENTRE) < HALF && y > CENTRE - HALF && y < CENTRE - HALF + 100);
  }
});

test('the walk stays inside the courtyard at eye height and comes back to its start', () => {
  const steps = 240;
  for (let i = 0; i <= steps; i++) {
    const c = walk(i, steps);
    assert.ok(Math.abs(c.x - CENTRE) < HALF - 300 && Math.abs(c.y - CENTRE) < HALF - 300, `step ${i} inside`);
    assert.equal(c.height, EYE);
  }
  const [a, b] = [walk(0, steps), walk(steps, steps)];
  assert.ok(Math.abs(a.x - b.x) < 1e-6 && Math.abs(a.y - b.y) < 1e-6);
});
