// Links to the viewer: a unique id prefix opens its texture; a link naming none says which
// texture it shows instead; the debugging hooks are defined only when a link asks for them.
import test, { after, before } from 'node:test';
import assert from 'node:assert/strict';
import { closeSession, openViewer, startSession, tileRequests, waitForIdle } from './lib.mjs';

let server;
let browser;
let textures;

before(async () => ({ server, browser, textures } = await startSession()));
after(() => closeSession({ server, browser }));

test('a unique prefix of an id opens that texture', async () => {
  const smallest = textures.reduce((a, b) => (b.width * b.height < a.width * a.height ? b : a));
  const prefix = smallest.id.slice(0, 8);
  assert.equal(textures.filter((t) => t.id.startsWith(prefix)).length, 1, 'the prefix is unique among the demos');
  const { page } = await openViewer(browser.context, `${server.url}/?texture=${prefix}`);
  assert.equal(await page.evaluate(() => window.vtexViewer.state.info.id), smallest.id);
  assert.equal(await page.locator('#error').isHidden(), true);
  await page.close();
});

test('a link naming no texture says which texture it shows: the one whose tiles are drawn', async () => {
  const { page, log } = await openViewer(browser.context, `${server.url}/?texture=no-such-texture`);
  await waitForIdle(page);
  const message = await page.locator('#error').textContent();
  const drawn = new Set(tileRequests(log.requests).map((t) => t.id));
  assert.equal(drawn.size, 1, 'tiles of one texture were fetched');
  const shown = textures.find((t) => t.id === [...drawn][0]);
  assert.ok(message.includes('"no-such-texture"') && message.includes(`showing ${shown.name}.`), message);
  assert.equal(await page.locator('#texture-picker').inputValue(), shown.id, 'the picker shows it too');
  await page.close();
});

test('the pages define their debugging hooks only when the link asks for them, and the viewer keeps asking', async () => {
  // The browser's own globals: those of a page with no script, from the same origin.
  const blank = await browser.context.newPage();
  await blank.goto(`${server.url}/osd/LICENSE.txt`);
  const builtIn = await blank.evaluate(() => Object.keys(window));
  await blank.close();
  const own = (page) => page.evaluate((known) => Object.keys(window).filter((k) => !known.includes(k)), builtIn);

  const page = await browser.context.newPage();
  const errors = [];
  page.on('pageerror', (e) => errors.push(String(e)));
  await page.goto(`${server.url}/`);
  await page.waitForFunction(() => /[?&]zoom=/.test(location.search)); // the view is written once it is open
  assert.deepEqual(await own(page), ['OpenSeadragon'], 'the viewer defines no global but the library it loads');
  assert.doesNotMatch(await page.evaluate(() => location.search), /debug/);
  await page.goto(`${server.url}/vt.html?format=rgba&camera=50000,50000,220,17,35`);
  await page.waitForFunction(() => document.getElementById('overlay').textContent.includes('resident'));
  assert.deepEqual(await own(page), [], 'the VT demo defines none');
  await page.goto(`${server.url}/world.html?pages=rgba&camera=50000,51000,160,0,8`);
  await page.waitForFunction(() => document.getElementById('overlay').textContent.includes('resident'));
  assert.deepEqual(await own(page), [], 'the world defines none');
  assert.deepEqual(errors, []);
  await page.close();

  const { page: asked } = await openViewer(browser.context, `${server.url}/?texture=${textures[0].id}`);
  assert.equal(typeof (await asked.evaluate(() => window.vtexViewer.getView())), 'object');
  await asked.waitForFunction(() => /[?&]zoom=/.test(location.search));
  assert.match(await asked.evaluate(() => location.search), /[?&]debug(=|&|$)/, 'the address the viewer writes keeps debug');
  await asked.close();
});
