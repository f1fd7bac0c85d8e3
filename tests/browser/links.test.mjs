// Links to the viewer: a unique id prefix opens its texture; a link naming none says which
// texture it shows instead.
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
