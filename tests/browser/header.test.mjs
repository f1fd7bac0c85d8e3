// The viewer's header at the narrow desktop sizes a newcomer may have: every control lies inside
// the window, above the map, uncovered at its centre, and takes a click.
import test, { after, before } from 'node:test';
import assert from 'node:assert/strict';
import { closeSession, openViewer, startSession, waitForIdle } from './lib.mjs';

const CONTROLS = ['#texture-picker', '#format', '#detail', '#synth', '#coords', '#zoom-readout', '#copy-link', '#vt-demo'];

let server;
let browser;

before(async () => ({ server, browser } = await startSession()));
after(() => closeSession({ server, browser }));

/** In the page: where `selector` is, whether the element at its centre is it, and the window's size. */
function placeOf(selector) {
  const el = document.querySelector(selector);
  const r = el.getBoundingClientRect();
  const top = document.elementFromPoint(r.left + r.width / 2, r.top + r.height / 2);
  return {
    box: { left: r.left, top: r.top, right: r.right, bottom: r.bottom },
    uncovered: top !== null && (top === el || el.contains(top)),
    window: { width: innerWidth, height: innerHeight },
    map: document.getElementById('osd').getBoundingClientRect().top,
  };
}

for (const size of [
  { width: 1024, height: 768 },
  { width: 1280, height: 800 },
]) {
  test(`at ${size.width} × ${size.height} every header control is visible, above the map and clickable`, async () => {
    const { page, log } = await openViewer(browser.context, `${server.url}/`);
    await page.setViewportSize(size);
    await waitForIdle(page);
    for (const selector of CONTROLS) {
      const { box, uncovered, window, map } = await page.evaluate(placeOf, selector);
      const where = `${selector} at ${JSON.stringify(box)}`;
      assert.ok(box.right > box.left && box.bottom > box.top, `${where} has a size`);
      assert.ok(box.left >= 0 && box.top >= 0 && box.right <= window.width && box.bottom <= window.height, `${where} lies inside the window`);
      assert.ok(box.bottom <= map, `${where} lies above the map (top ${map})`);
      assert.ok(uncovered, `${where} is the element at its centre`);
      // Playwright's own checks before a click: visible, stable, enabled, receiving the pointer.
      await page.locator(selector).click({ trial: true, timeout: 5000 });
    }
    // The answer comes after the clipboard's promise settles, so it is awaited, not read at once.
    await page.click('#copy-link');
    const answered = await page
      .waitForFunction(() => document.querySelector('#copy-link').textContent !== 'Copy link', null, { timeout: 5000 })
      .then(() => true, () => false);
    assert.ok(answered, 'Copy link answered the click');
    assert.deepEqual(log.errors, []);
    await Promise.all([page.waitForURL(/\/vt\.html$/), page.click('#vt-demo')]);
    await page.close();
  });
}
