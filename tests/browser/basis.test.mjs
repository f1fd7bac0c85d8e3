// vtex's Basis Universal KTX2 pages (codec uastc and etc1s) read by a reader no one here wrote:
// three.js's stock KTX2Loader (npm `three`, with the Basis transcoder it ships in
// examples/jsm/libs/basis/) in headless Chromium, loading pages of several models from a live
// vtex serve. The loader is told the device supports no compressed format (a renderer with no
// WEBGL_compressed_texture_* extension, as a GPU without them is), so its transcoder makes RGBA32,
// which is compared, pixel for pixel, with the server's RGBA page: PSNR at least UASTC_DB /
// ETC1S_DB, the colour space sRGB (the DFD's transfer function), every mip level of a chain
// there and of the right size.
// Run: node --test tests/browser/   (needs target/release/vtex and client-web/dist built)
import test, { after, before } from 'node:test';
import assert from 'node:assert/strict';
import { join } from 'node:path';
import { launchBrowser, ROOT, startServer } from './lib.mjs';

// Floors of each page's PSNR over its RGB channels (alpha compared apart, where a page has it),
// some 2 dB under the lowest measured on these pages, a noisy cascade at level 2 (UASTC 35.9 dB,
// ETC1S 22.1 dB; docs/ktx2-quality.md has the figures): a page shifted by a pixel or a wrong
// colour model falls far below, a wrong transfer function fails the colour-space check.
const UASTC_DB = 33;
const ETC1S_DB = 20;
// How much closer than the page's mean colour a transcoded page must be: a page's flat mean
// reaches ETC1S_DB on half of these pages (up to 24.2 dB), so each page is also held to its own
// trivial answer (ETC1S beats it by 6.2–14.8 dB here, UASTC by 20 or more).
const FLAT_MARGIN_DB = 5;
const NPM = '/node_modules';
// Several models, each at a level whose page has detail, at a page away from the origin.
const MODELS = 5;
const PAGES = [
  { level: 0, x: 3, y: 2, size: 256, border: 4 },
  { level: 2, x: 1, y: 1, size: 128, border: 2 },
];

let server;
let browser;
let page;
let textures;

before(async () => {
  server = await startServer();
  browser = await launchBrowser({ width: 256, height: 256 });
  ({ textures } = await (await fetch(`${server.url}/api/v1/textures`)).json());
  // One texture of each model, the first MODELS of them.
  const seen = new Set();
  textures = textures.filter((t) => !seen.has(t.model) && seen.add(t.model)).slice(0, MODELS);
  assert.ok(textures.length >= 3, 'the demo textures cover at least 3 models');
  page = await browser.context.newPage();
  page.on('pageerror', (e) => console.error(String(e)));
  const html = `<!doctype html><html><head><script type="importmap">
    { "imports": { "three": "${NPM}/three/build/three.module.js", "three/addons/": "${NPM}/three/examples/jsm/" } }
  </script><script type="module">
    import * as THREE from 'three';
    import { KTX2Loader } from 'three/addons/loaders/KTX2Loader.js';
    const loader = new KTX2Loader().setTranscoderPath('${NPM}/three/examples/jsm/libs/basis/');
    // A WebGL renderer's extensions, none of them a compressed texture format.
    loader.detectSupport({ extensions: { has: () => false, get: () => null } });
    window.loadKtx2 = async (url) => {
      const t = await loader.loadAsync(url);
      const levels = t.mipmaps.map((m) => ({ width: m.width, height: m.height, data: Array.from(m.data) }));
      const out = {
        levels,
        colorSpace: t.colorSpace,
        rgba: t.format === THREE.RGBAFormat && t.type === THREE.UnsignedByteType,
        srgb: THREE.SRGBColorSpace,
      };
      t.dispose();
      return out;
    };
    window.ready = true;
  </script></head><body></body></html>`;
  await page.route(`${server.url}/basis-test.html`, (route) => route.fulfill({ body: html, contentType: 'text/html' }));
  await page.route(`${server.url}${NPM}/**`, (route) =>
    route.fulfill({ path: join(ROOT, 'client-web', new URL(route.request().url()).pathname) }),
  );
  await page.goto(`${server.url}/basis-test.html`);
  await page.waitForFunction(() => window.ready === true, null, { timeout: 30_000 });
});

after(async () => {
  await page?.close();
  await browser?.close();
  await server?.stop();
});

/** PSNR (dB) of `a` against `b`, RGBA8 alike, over channels `channels` (indices 0–3). */
function psnr(a, b, channels) {
  let sum = 0;
  let n = 0;
  for (let i = 0; i < a.length; i += 4) {
    for (const c of channels) {
      const d = a[i + c] - b[i + c];
      sum += d * d;
      n++;
    }
  }
  return sum === 0 ? Infinity : 10 * Math.log10((255 * 255 * n) / sum);
}

/** `img` (w × h RGBA8) moved by (dx, dy) pixels, its edge repeated. */
function shifted(img, w, h, dx, dy) {
  const out = new Uint8Array(img.length);
  for (let y = 0; y < h; y++) {
    for (let x = 0; x < w; x++) {
      const sx = Math.min(w - 1, Math.max(0, x + dx));
      const sy = Math.min(h - 1, Math.max(0, y + dy));
      out.set(img.subarray((sy * w + sx) * 4, (sy * w + sx) * 4 + 4), (y * w + x) * 4);
    }
  }
  return out;
}

/**
 * The decoded `got` is the server's `want` and not a neighbour's: closer to it than to `want`
 * moved by one pixel any way, by at least 1 dB (smooth pages are within any fixed floor of
 * their own shift). A way in which moving `want` changes it less than the codec's error does
 * cannot tell a shift from the codec, and is skipped. Returns the failure, or null.
 */
function notShifted(got, want, w, h) {
  const db = psnr(got, want, [0, 1, 2]);
  for (const [dx, dy] of [[1, 0], [-1, 0], [0, 1], [0, -1]]) {
    const moved = shifted(want, w, h, dx, dy);
    if (psnr(want, moved, [0, 1, 2]) >= db) continue;
    const other = psnr(got, moved, [0, 1, 2]);
    if (!(db >= other + 1)) return `${db.toFixed(2)} dB, but ${other.toFixed(2)} dB against the page moved by (${dx}, ${dy})`;
  }
  return null;
}

/** `img` (RGBA8) with every pixel its mean colour: the trivial answer a floor must reject. */
function flat(img) {
  const sum = [0, 0, 0, 0];
  for (let i = 0; i < img.length; i++) sum[i % 4] += img[i];
  const n = img.length / 4;
  return img.map((_, i) => Math.round(sum[i % 4] / n));
}

async function bytes(url) {
  const r = await fetch(url);
  assert.equal(r.status, 200, `${url}: ${r.status} ${r.status === 200 ? '' : await r.text()}`);
  return new Uint8Array(await r.arrayBuffer());
}

for (const [codec, floor] of [
  ['uastc', UASTC_DB],
  ['etc1s', ETC1S_DB],
]) {
  test(`three.js's KTX2Loader transcodes vtex's ${codec} pages to the server's pixels`, async () => {
    const rows = [];
    const low = [];
    for (const t of textures) {
      for (const p of PAGES) {
        const base = `${server.url}/api/v1/textures/${t.id}/pages/${p.level}/${p.x}/${p.y}`;
        const q = `size=${p.size}&border=${p.border}`;
        const want = await bytes(`${base}.rgba?${q}`);
        const got = await page.evaluate((url) => window.loadKtx2(url), `${base}.ktx2?${q}&codec=${codec}`);
        const side = p.size + 2 * p.border;
        assert.equal(got.levels.length, 1, 'a page is one level');
        assert.deepEqual([got.levels[0].width, got.levels[0].height], [side, side]);
        assert.ok(got.rgba, 'transcoded to RGBA8, as a device without compressed formats gets');
        assert.equal(got.colorSpace, got.srgb, `${t.name}: the DFD says sRGB`);
        const db = psnr(got.levels[0].data, want, [0, 1, 2]);
        const opaque = want.every((v, i) => i % 4 !== 3 || v === 255);
        const alphaDb = opaque ? null : psnr(got.levels[0].data, want, [3]);
        rows.push(`${t.name} L${p.level} ${side}²: ${db.toFixed(2)} dB${alphaDb === null ? '' : `, alpha ${alphaDb.toFixed(2)} dB`}`);
        if (db < floor) low.push(`${t.name} page ${p.level}/${p.x}/${p.y}: ${db.toFixed(2)} dB < ${floor} dB`);
        // A page's mean colour is no answer: the codec must beat it by FLAT_MARGIN_DB.
        const flatDb = psnr(flat(want), want, [0, 1, 2]);
        if (!(db >= flatDb + FLAT_MARGIN_DB)) low.push(`${t.name} page ${p.level}/${p.x}/${p.y}: ${db.toFixed(2)} dB, its mean colour ${flatDb.toFixed(2)} dB`);
        const moved = notShifted(got.levels[0].data, want, side, side);
        if (moved) low.push(`${t.name} page ${p.level}/${p.x}/${p.y}: ${moved}`);
        if (!opaque && alphaDb < floor) low.push(`${t.name}: alpha ${alphaDb.toFixed(2)} dB < ${floor} dB`);
        if (opaque) assert.ok(got.levels[0].data.every((v, i) => i % 4 !== 3 || v === 255), 'an opaque page stays opaque');
      }
    }
    console.log(`${codec}:\n  ${rows.join('\n  ')}`);
    assert.deepEqual(low, [], 'every page over the floor');
  });

  test(`three.js's KTX2Loader reads a ${codec} mip chain, every level the server's`, async () => {
    const t = textures[0];
    // Level sizes round up (vtex-synth's level_size); the chain from the first of at most 256 a
    // side, to 1×1.
    const size = (l) => [Math.ceil(t.width / 2 ** l), Math.ceil(t.height / 2 ** l)];
    let level = 0;
    while (Math.max(...size(level)) > 256) level++;
    const got = await page.evaluate(
      (url) => window.loadKtx2(url),
      `${server.url}/api/v1/textures/${t.id}/mips.ktx2?level=${level}&codec=${codec}`,
    );
    const [width, height] = size(level);
    assert.equal(got.levels.length, Math.floor(Math.log2(Math.max(width, height))) + 1);
    assert.equal(got.colorSpace, got.srgb);
    for (const [i, l] of got.levels.entries()) {
      assert.deepEqual([l.width, l.height], [Math.max(1, width >> i), Math.max(1, height >> i)], `level ${i}`);
      if (l.width < 8) continue;
      // Level i of the chain is the top left of vtex level `level + i`: its region.
      const region = `${server.url}/api/v1/textures/${t.id}/region?level=${level + i}&x=0&y=0&w=${l.width}&h=${l.height}&format=rgba`;
      const want = await bytes(region);
      const db = psnr(l.data, want, [0, 1, 2]);
      assert.ok(db >= floor - 2, `chain level ${i}: ${db.toFixed(2)} dB`);
      const moved = notShifted(l.data, want, l.width, l.height);
      assert.equal(moved, null, `chain level ${i}`);
    }
  });
}
