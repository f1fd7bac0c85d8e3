// `vtex export-web`: the exported folder, served by Python's http.server with no vtex running,
// opens in Chromium and draws the texture synthesized in the page, equal to `vtex render`.
// Run: node --test tests/browser/   (needs target/release/vtex and client-web/dist built with
// the wasm module; see scripts/test)
import test, { after, before } from 'node:test';
import assert from 'node:assert/strict';
import { execFileSync } from 'node:child_process';
import { mkdtempSync, readFileSync, readdirSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { VTEX_BIN, WEB_DIR, compareScreenToImage, exited, launchBrowser, openViewer, setAlignedView, startServer, staticServer, waitForIdle } from './lib.mjs';

let work;
let browser;

before(async () => {
  work = mkdtempSync(join(tmpdir(), 'vtex-export-'));
  browser = await launchBrowser({ width: 800, height: 520 });
});

after(async () => {
  await browser?.close();
  rmSync(work, { recursive: true, force: true });
});

const vtex = (...args) => execFileSync(VTEX_BIN, args, { encoding: 'utf8', env: { ...process.env, VTEX_LOG: 'warn' } });

test('an exported folder served by a plain static server shows the texture, synthesized in the page', async () => {
  // The demos' bundles: from a vtex data directory, then vtex is stopped for good.
  const server = await startServer();
  const data = join(work, 'data');
  execFileSync('cp', ['-r', server.dataDir, data]);
  const textures = (await (await fetch(`${server.url}/api/v1/textures`)).json()).textures;
  await server.stop();
  const info = textures.find((t) => t.model === 'chaos-mosaic' && t.width >= 100_000);
  const dir = join(work, 'export');
  const said = vtex('export-web', info.id, dir, '--data-dir', data, '--web-dir', WEB_DIR);
  assert.match(said, new RegExp(`\\d+ files, \\d+ bytes \\(${info.encoding_bytes} the encoding\\)`));
  assert.deepEqual(readdirSync(join(dir, 'textures')), [`${info.id}.vtex`]);
  assert.deepEqual(readFileSync(join(dir, 'textures', `${info.id}.vtex`)), readFileSync(join(data, `${info.id}.vtex`)));
  assert.match(vtex('info', join(dir, 'textures', `${info.id}.vtex`)), new RegExp(`"id": "${info.id}"`));
  // Exporting into a folder that is not empty is refused.
  assert.throws(() => execFileSync(VTEX_BIN, ['export-web', info.id, dir, '--data-dir', data], { stdio: 'pipe' }), /is not empty/);

  const site = await staticServer(dir);
  try {
    const { page, log } = await openViewer(browser.context, `${site.url}/?texture=${info.id}`);
    await waitForIdle(page, 120_000);
    const [x, y] = [73_000 + 40, 41_000 + 20];
    await setAlignedView(page, 1, x, y);
    assert.deepEqual(await page.evaluate(() => window.vtexViewer.drawnLevels()), [0]);
    const native = join(work, 'patch.rgba');
    vtex('render', join(dir, 'textures', `${info.id}.vtex`), '--level', '0', '--x', String(x), '--y', String(y), '--width', '32', '--height', '32', '--out', native);
    assert.equal(await compareScreenToImage(page, { width: 32, height: 32, data: readFileSync(native) }, 0, 0, 0, x, y, 32), 0, 'pixels of `vtex render`');
    const state = await page.evaluate(() => ({
      mode: window.vtexViewer.state.synthMode,
      control: document.getElementById('synth').disabled,
      error: document.getElementById('error').hidden ? null : document.getElementById('error').textContent,
      name: document.getElementById('texture-picker').selectedOptions[0].textContent,
    }));
    assert.deepEqual(state, { mode: 'client', control: true, error: null, name: state.name });
    assert.match(state.name, /^Pebbles — chaos mosaic 100k/);
    assert.deepEqual(log.errors, [], 'console errors');
    assert.deepEqual(log.badResponses, [], 'error responses');
    assert.deepEqual(log.requests.filter((u) => new URL(u).pathname.startsWith('/api/')), [], 'no API request');
    assert.deepEqual(log.requests.filter((u) => !u.startsWith(site.url) && /^https?:/.test(u)), [], 'no other origin');
    await page.close();
  } finally {
    await site.stop();
  }
});
