// What a newcomer sees: the viewer opened without a link shows a texture's structure (not the
// mean colour of a texture zoomed fully out), and a torus wraps past its edges as its info says.
import test, { after, before } from 'node:test';
import assert from 'node:assert/strict';
import { mkdirSync, writeFileSync } from 'node:fs';
import { join } from 'node:path';
import {
  ROOT,
  closeSession,
  compareScreenToImage,
  fetchServerTile,
  openViewer,
  setAlignedView,
  startSession,
  structure,
  tileRequests,
  viewCentre,
  waitForIdle,
} from './lib.mjs';
import { FIRST_ZOOM, SHOWCASE } from '../../client-web/src/viewer/first-view.js';
import { inPyramid, tileCount } from '../../client-web/src/viewer/pyramid.js';

const SHOTS = join(ROOT, 'target', 'browser-shots');

let server;
let browser;
let textures;

before(async () => ({ server, browser, textures } = await startSession()));
after(() => closeSession({ server, browser }));

test('the viewer opened without a link shows the showcase texture with its structure visible', async () => {
  const { page, log } = await openViewer(browser.context, `${server.url}/`);
  await waitForIdle(page);
  const shown = await page.evaluate(() => ({ name: window.vtexViewer.state.info.name, levels: window.vtexViewer.drawnLevels() }));
  mkdirSync(SHOTS, { recursive: true });
  writeFileSync(join(SHOTS, 'first-open.png'), await page.screenshot());
  const s = structure(await viewCentre(page));
  // Zoomed fully out, the largest demo (Cascade F) shows 16 such colours and a luma deviation
  // of 5.8, the 100k demos 3–4 colours and under 2; the showcase at its first zoom over 100 and 25.
  assert.ok(s.colours >= 50, `${s.colours} common colours in the view`);
  assert.ok(s.sd >= 12, `luma standard deviation ${s.sd.toFixed(1)}`);
  assert.equal(shown.name, SHOWCASE, 'the showcase (first-view.js SHOWCASE names a demo the server writes)');
  assert.deepEqual(log.errors, []);
  assert.deepEqual(log.badResponses, []);
  assert.equal(await page.locator('#error').isHidden(), true, 'no message');
  await page.close();
});

test('a texture picked in the list opens as the first one does, where its structure shows', async () => {
  // Opened on a small texture, shown whole; then each 100k texture picked in turn.
  const small = textures.find((t) => t.width <= 2048 && t.height <= 2048 && !t.animated);
  const picked = [textures.find((t) => t.name === SHOWCASE), textures.find((t) => t.name === 'LCM pebbles 100k')];
  const { page, log } = await openViewer(browser.context, `${server.url}/?texture=${small.id}`);
  await waitForIdle(page);
  for (const info of picked) {
    assert.ok(info.width >= 100_000, info.name);
    await page.selectOption('#texture-picker', info.id);
    await page.waitForFunction((id) => window.vtexViewer.state.info.id === id && window.vtexViewer.state.item, info.id);
    await waitForIdle(page);
    const s = structure(await viewCentre(page));
    const view = await page.evaluate(() => window.vtexViewer.getView());
    assert.ok(Math.abs(view.zoom - FIRST_ZOOM) < 1e-9, `${info.name} opens at the first view's zoom, not ${view.zoom}`);
    assert.ok(s.colours >= 50, `${info.name}: ${s.colours} common colours in the view`);
    assert.ok(s.sd >= 12, `${info.name}: luma standard deviation ${s.sd.toFixed(1)}`);
  }
  assert.deepEqual(log.errors, []);
  assert.deepEqual(log.badResponses, []);
  await page.close();
});

test('a torus wraps: past its edges the view shows the tiles at the wrapped coordinates', async () => {
  const torus = textures.find((t) => t.name === SHOWCASE);
  assert.equal(torus.domain, 'torus');
  assert.ok(torus.wraps);
  // A width that is not a multiple of the tile size: the last column of tiles is clipped.
  assert.notEqual(torus.width % torus.tile_size, 0);
  const { page, log } = await openViewer(browser.context, `${server.url}/?texture=${torus.id}&zoom=1&x=300&y=300`);
  await waitForIdle(page);
  // Drag the view up and left past the texture's corner: nothing holds it back.
  const box = await page.locator('#osd').boundingBox();
  const [cx, cy] = [box.x + box.width / 2, box.y + box.height / 2];
  await page.mouse.move(cx, cy);
  await page.mouse.down();
  for (let i = 1; i <= 10; i++) await page.mouse.move(cx + 50 * i, cy + 50 * i);
  await page.mouse.up();
  await waitForIdle(page);
  // Once the pan ends the view is brought back by a period, onto the same pixels.
  await page.waitForFunction(() => window.vtexViewer.getView().x > 0);
  await waitForIdle(page);
  const view = await page.evaluate(() => window.vtexViewer.getView());
  for (const [v, size] of [[view.x, torus.width], [view.y, torus.height]]) {
    assert.ok(Math.abs(v - (size - 200)) < 1, `the view's centre (${view.x}, ${view.y}) lies 200 px before the far corner`);
  }
  const navigator = await page.locator('.navigator').boundingBox();
  const region = await page.locator('.displayregion').boundingBox();
  const inside = (a, lo, size) => a > lo + size / 2 && a < lo + size;
  assert.ok(inside(region.x, navigator.x, navigator.width) && inside(region.y, navigator.y, navigator.height), `the navigator's box ${JSON.stringify(region)} lies in the far quarter of the navigator ${JSON.stringify(navigator)}`);

  // At `level` drawn 1:1, a view set on the corner (0, 0) is brought back to the far corner
  // (W, H): the 32² patches just before it and just past it equal the server's tiles at the
  // wrapped coordinates, the last tile (clipped) and the first.
  for (const level of [0, 2]) {
    const s = 2 ** level;
    const n = tileCount(torus, level);
    const last = await fetchServerTile(server.url, torus, level, n.x - 1, n.y - 1);
    const first = await fetchServerTile(server.url, torus, level, 0, 0);
    await setAlignedView(page, 1 / s, -16 * s, -16 * s);
    await page.waitForFunction(() => window.vtexViewer.getView().x > 0);
    await waitForIdle(page);
    assert.deepEqual(await page.evaluate(() => window.vtexViewer.drawnLevels()), [level]);
    const far = { x: torus.width / s, y: torus.height / s };
    const before = await compareScreenToImage(page, last, last.width - 32, last.height - 32, level, far.x - 32, far.y - 32);
    assert.equal(before, 0, `level ${level}: the patch before the far corner`);
    assert.equal(await compareScreenToImage(page, first, 0, 0, level, far.x, far.y), 0, `level ${level}: the patch past it`);
  }
  for (const t of tileRequests(log.requests)) assert.ok(inPyramid(torus, t.level, t.x, t.y), `tile ${t.level}/${t.x}/${t.y} inside the pyramid`);
  assert.deepEqual(log.errors, []);
  assert.deepEqual(log.badResponses, []);
  await page.close();
});

test('a plane does not wrap: a pan stops at its edge', async () => {
  const plane = textures.find((t) => t.domain === 'plane' && !t.wraps);
  const { page, log } = await openViewer(browser.context, `${server.url}/?texture=${plane.id}&zoom=1&x=300&y=300`);
  await waitForIdle(page);
  await page.evaluate(() => {
    const { viewer, state } = window.vtexViewer;
    viewer.viewport.panTo(state.item.imageToViewportCoordinates(-5000, -5000), true);
    viewer.viewport.applyConstraints(true);
  });
  await waitForIdle(page);
  const view = await page.evaluate(() => window.vtexViewer.getView());
  assert.ok(view.x > -1000 && view.y > -1000, `the view (${view.x}, ${view.y}) was held near the texture`);
  for (const t of tileRequests(log.requests)) assert.ok(inPyramid(plane, t.level, t.x, t.y));
  assert.deepEqual(log.badResponses, []);
  await page.close();
});
