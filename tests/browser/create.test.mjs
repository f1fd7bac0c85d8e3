// The viewer's panel that creates a texture (client-web/src/viewer/create-panel.js): its form, made
// from each model's JSON Schema, holds the model's example exactly; what it posts makes the
// same texture as the same upload made by hand; the viewer opens the result; the server's
// refusals (a bad parameter, a missing write token, a read-only server) show in the panel.
import test, { after, before } from 'node:test';
import assert from 'node:assert/strict';
import {
  compareScreenToServerTile,
  debugUrl,
  encodePng,
  launchBrowser,
  openViewer,
  setAlignedView,
  startServer,
  tileRequests,
  waitForIdle,
} from './lib.mjs';
import { parseJson, stringifyJson } from '../../client-web/src/viewer/schema-form.js';

let server;
let browser;
let models;

before(async () => {
  server = await startServer();
  browser = await launchBrowser({ height: 1000 });
  // Parsed as the panel parses it: u64 seeds stay exact.
  models = parseJson(await (await fetch(`${server.url}/api/v1/models`)).text()).models;
});

after(async () => {
  await browser?.close();
  await server?.stop();
});

const model = (id) => {
  const m = models.find((x) => x.id === id);
  assert.ok(m, `the server lists model ${id}`);
  return m;
};

/** A project-made sample: soft discs on a gradient, `w` × `h`. */
function samplePng(w, h) {
  const data = Buffer.alloc(w * h * 4);
  for (let y = 0; y < h; y++) {
    for (let x = 0; x < w; x++) {
      const d = Math.hypot((x % 12) - 6, (y % 10) - 5);
      const i = (y * w + x) * 4;
      data[i] = d < 4 ? 210 - 20 * d : 70 + x;
      data[i + 1] = d < 4 ? 150 : 60 + y;
      data[i + 2] = 40 + ((x * y) % 50);
      data[i + 3] = 255;
    }
  }
  return encodePng(w, h, data);
}

/** Opens the viewer and its creation panel on `url`, with `id`'s model picked. */
async function openPanel(url, id) {
  const { page, log } = await openViewer(browser.context, `${url}/`);
  await page.click('#create-toggle');
  await page.waitForSelector('#create-model:not([disabled])');
  if (id) await page.selectOption('#create-model', id);
  return { page, log };
}

/** Clicks Create and resolves with the panel's status once the server has answered. */
async function create(page) {
  await page.click('#create-submit');
  await page.waitForFunction(() => {
    const s = document.getElementById('create-status');
    return !s.hidden && s.textContent !== 'Creating…' && !document.getElementById('create-submit').disabled;
  });
  return { text: await page.locator('#create-status').textContent(), kind: await page.locator('#create-status').getAttribute('class') };
}

/** The same upload made by hand: `params` and the `inputs` ({ name: PNG bytes }) as multipart. */
async function uploadByHand(url, id, name, params, inputs = {}, headers = {}) {
  const form = new FormData();
  form.append('model', id);
  form.append('name', name);
  form.append('params', stringifyJson(params));
  for (const [k, png] of Object.entries(inputs)) form.append(k, new Blob([png], { type: 'image/png' }), `${k}.png`);
  const r = await fetch(`${url}/api/v1/textures`, { method: 'POST', body: form, headers });
  return { status: r.status, body: await r.json() };
}

/** The example's input images, fetched from the server ({ name: bytes }). */
async function exampleInputs(m) {
  const out = {};
  for (const [name, input] of Object.entries(m.example.inputs)) out[name] = Buffer.from(await (await fetch(input.href)).arrayBuffer());
  return out;
}

/** The parameters the panel holds, read through its JSON view (and the form rebuilt from it). */
async function panelParams(page) {
  await page.click('#create-params-mode');
  const text = await page.locator('#create-params-json').inputValue();
  await page.click('#create-params-mode');
  return parseJson(text);
}

/** `v` without its object members that are null: serde reads a missing Option as null. */
function withoutNulls(v) {
  if (Array.isArray(v)) return v.map(withoutNulls);
  if (v && typeof v === 'object') return Object.fromEntries(Object.entries(v).filter(([, x]) => x !== null).map(([k, x]) => [k, withoutNulls(x)]));
  return v;
}

test("every model's form, generated from its schema, holds its example and creates the example's texture", async () => {
  assert.ok(models.length >= 5, `${models.length} models`);
  const { page, log } = await openPanel(server.url);
  for (const m of models) {
    await page.selectOption('#create-model', m.id);
    const fields = await page.evaluate(() => document.querySelectorAll('#create-params [data-path]').length);
    assert.ok(fields > 1, `${m.id}: the form has fields`);
    const expected = withoutNulls(m.example.params);
    assert.deepEqual(await panelParams(page), expected, `${m.id}: the form reads back the example`);
    // Rebuilt from the JSON view, the form still holds it.
    assert.deepEqual(await panelParams(page), expected, `${m.id}: again after a round through JSON`);
    // What the panel posts makes the example's texture.
    const status = await create(page);
    assert.equal(status.kind, 'ok', `${m.id}: ${status.text}`);
    await page.waitForFunction((id) => window.vtexViewer.state.info.model === id, m.id);
    const made = await page.evaluate(() => window.vtexViewer.state.info.id);
    const byHand = await uploadByHand(server.url, m.id, m.title, m.example.params, await exampleInputs(m));
    assert.equal(byHand.status, 200, `${m.id}: the example upload by hand finds it stored`);
    assert.equal(byHand.body.id, made, `${m.id}: the same texture`);
  }
  assert.deepEqual(log.errors, []);
  await page.close();
});

test('the panel creates a chaos mosaic from an uploaded sample, as the same upload by hand, and the viewer opens it', async () => {
  const m = model('chaos-mosaic');
  const { page, log } = await openPanel(server.url, m.id);
  const png = samplePng(48, 40);
  // 768 × 480: larger than the view at 1:1, so the view can be set to 1:1.
  await page.fill('#create-name', 'Discs — made in the panel');
  await page.getByLabel('params.tiles_x', { exact: true }).fill('16');
  await page.getByLabel('params.tiles_y', { exact: true }).fill('12');
  await page.getByLabel('input sample').setInputFiles({ name: 'discs.png', mimeType: 'image/png', buffer: png });
  const params = await panelParams(page);
  assert.equal(params.tiles_x, 16);
  const status = await create(page);
  assert.equal(status.kind, 'ok', status.text);
  assert.match(status.text, /^Created: Discs — made in the panel — 768 × 480, encoding /);
  await page.waitForFunction(() => window.vtexViewer.state.info.name === 'Discs — made in the panel' && window.vtexViewer.state.item);
  const info = await page.evaluate(() => window.vtexViewer.state.info);
  assert.equal(info.model, 'chaos-mosaic');
  assert.deepEqual([info.width, info.height], [768, 480], 'tiles_x × the sample width, tiles_y × its height');
  assert.equal(await page.locator('#texture-picker').inputValue(), info.id, 'the picker lists and selects it');
  // The panel posted exactly these parameters and this image: by hand they make the same texture.
  const byHand = await uploadByHand(server.url, m.id, 'Discs — made in the panel', params, { sample: png });
  assert.equal(byHand.status, 200, 'already stored');
  assert.equal(byHand.body.id, info.id);
  await waitForIdle(page);
  assert.ok(tileRequests(log.requests).some((t) => t.id === info.id), "the new texture's tiles were fetched");
  await setAlignedView(page, 1, 300, 200);
  assert.equal(await compareScreenToServerTile(page, server.url, info, 0, 300, 200, 32), 0, "the view shows the server's tile");
  assert.deepEqual(log.errors, []);
  await page.close();
});

test("the panel creates a texture of a model without input images from its edited example", async () => {
  const m = models.find((x) => x.inputs.every((i) => !i.required) && Object.keys(x.example.inputs).length === 0);
  assert.ok(m, 'a model that needs no input image');
  const { page, log } = await openPanel(server.url, m.id);
  const seed = m.example.params.seed === 4242 ? 4243 : 4242;
  await page.getByLabel('params.seed', { exact: true }).fill(String(seed));
  const params = await panelParams(page);
  assert.deepEqual(params, { ...m.example.params, seed });
  const status = await create(page);
  assert.equal(status.kind, 'ok', status.text);
  await page.waitForFunction(([id, title]) => {
    const { state } = window.vtexViewer;
    return state.item && state.info.model === id && state.info.name === title;
  }, [m.id, m.title]);
  const info = await page.evaluate(() => window.vtexViewer.state.info);
  assert.equal(info.model, m.id);
  const byHand = await uploadByHand(server.url, m.id, m.title, params);
  assert.equal(byHand.body.id, info.id, 'the same texture as the same upload by hand');
  await waitForIdle(page);
  assert.ok(tileRequests(log.requests).some((t) => t.id === info.id), "the new texture's tiles were fetched");
  assert.deepEqual(log.errors, []);
  await page.close();
});

test('entries added to and removed from a list keep paths that follow their places', async () => {
  const m = model('cascade');
  const stages = m.example.params.stages;
  const { page } = await openPanel(server.url, m.id);
  const paths = () => page.evaluate(() => [...document.querySelectorAll('#create-params [data-path^="params.stages["]')].map((f) => f.dataset.path.match(/^params\.stages\[\d+\]/)[0]));
  const list = page.locator('#create-params [data-path="params.stages"]');
  await list.locator(':scope > .schema-add').click();
  assert.ok((await paths()).includes(`params.stages[${stages.length}]`), 'the added entry is the last');
  await list.locator(':scope > .schema-list > li').first().locator(':scope > .schema-remove').click();
  const after = new Set(await paths());
  assert.deepEqual([...after], stages.map((_, i) => `params.stages[${i}]`), 'numbered from 0 again');
  assert.deepEqual((await panelParams(page)).stages.slice(0, -1), withoutNulls(stages.slice(1)), 'the entries after the removed one, moved up');
  await page.close();
});

test("a bad parameter shows the server's error in the panel; a field that is not a number is named before sending", async () => {
  const m = model('chaos-mosaic');
  const { page, log } = await openPanel(server.url, m.id);
  const before = await page.evaluate(() => window.vtexViewer.state.info.id);
  await page.getByLabel('params.c_lambda', { exact: true }).fill('5');
  const params = await panelParams(page);
  const status = await create(page);
  const byHand = await uploadByHand(server.url, m.id, m.title, params, await exampleInputs(m));
  assert.ok(byHand.status >= 400 && byHand.status < 500, JSON.stringify(byHand.body));
  assert.equal(status.kind, 'error');
  assert.equal(status.text, `The server refused it (HTTP ${byHand.status}): ${byHand.body.error}`);
  assert.match(byHand.body.error, /c_lambda/, 'the error names the parameter');
  const marked = await page.evaluate(() => [...document.querySelectorAll('#create-params .refused')].map((f) => f.dataset.path));
  assert.deepEqual(marked.sort(), ['params.c_lambda', 'params.c_mu'], 'the fields the error names are marked');
  assert.equal(await page.evaluate(() => window.vtexViewer.state.info.id), before, 'the view stays');

  const posts = () => log.requests.filter((u) => u.endsWith('/api/v1/textures')).length;
  const sent = posts();
  await page.getByLabel('params.seed', { exact: true }).fill('12.5');
  const local = await create(page);
  assert.equal(local.text, 'params.seed: "12.5" is not an integer');
  assert.equal(posts(), sent, 'nothing was sent');
  await page.close();
});

test('a server that needs a write token, or takes no writes, says so in the panel', async () => {
  const tokened = await startServer({ extraArgs: ['--no-demos', '--write-token', 'open-sesame'] });
  const readOnly = await startServer({ extraArgs: ['--no-demos', '--read-only'] });
  const page = await browser.context.newPage();
  try {
    const m = model('chaos-mosaic');
    const sample = await exampleInputs(m);
    // A server without textures shows the panel all the same.
    const panelOn = async (url) => {
      await page.goto(debugUrl(`${url}/`));
      await page.click('#create-toggle');
      await page.waitForSelector('#create-model:not([disabled])');
      await page.selectOption('#create-model', m.id);
    };
    await panelOn(tokened.url);
    const unauthorized = await uploadByHand(tokened.url, m.id, m.title, m.example.params, sample);
    assert.equal(unauthorized.status, 401);
    const refused = await create(page);
    assert.equal(refused.text, `The server needs its write token (HTTP 401): ${unauthorized.body.error}`);
    assert.equal(await page.locator('#create-token-box').getAttribute('open'), '', 'the token field is opened');
    await page.fill('#create-token', 'open-sesame');
    const done = await create(page);
    assert.equal(done.kind, 'ok', done.text);
    await page.waitForFunction(() => window.vtexViewer.state.item && window.vtexViewer.state.info.name);

    await panelOn(readOnly.url);
    const forbidden = await uploadByHand(readOnly.url, m.id, m.title, m.example.params, sample);
    assert.equal(forbidden.status, 403);
    assert.match(forbidden.body.error, /read-only/);
    const readOnlyStatus = await create(page);
    assert.equal(readOnlyStatus.text, `The server refuses writes (HTTP 403): ${forbidden.body.error}`);
  } finally {
    await page.close();
    await tokened.stop();
    await readOnly.stop();
  }
});
