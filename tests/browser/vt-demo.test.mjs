// The WebGL virtual-texturing demo (client-web/src/vt.html) in headless Chromium's software
// WebGL against a real vtex serve: at a fixed camera, once every page it needs is resident, its
// frame equals a trilinear reference render computed here from the server's regions (not its
// pages); while pages arrive, each pixel's refinement is spread over frames, not one pop; no
// page is requested while resident or in flight, also in a fly-through that evicts; the network
// is asked for single pages and page metatiles only, each one a fetch the demo logged.
// Run: node --test tests/browser/   (needs target/release/vtex and client-web/dist built)
import test, { after, before } from 'node:test';
import assert from 'node:assert/strict';
import { mkdirSync, writeFileSync } from 'node:fs';
import { join } from 'node:path';
import { debugUrl, decodePng, launchBrowser, ROOT, startServer } from './lib.mjs';

const VIEW = { width: 640, height: 400 };
// Pitched 35° down: levels 0 to 4 and beyond in one frame, the page grid crossed many times.
const CAMERA = { x: 50_000.25, y: 50_000.75, height: 220, yaw: 17, pitch: 35, fov: 60 };
const FLAGSHIP = 'Pebbles — chaos mosaic 100k';

let server;
let browser;
let info;

before(async () => {
  server = await startServer();
  browser = await launchBrowser(VIEW);
  const { textures } = await (await fetch(`${server.url}/api/v1/textures`)).json();
  info = textures.find((t) => t.name === FLAGSHIP);
  assert.ok(info, `the demo textures include ${FLAGSHIP}`);
});

after(async () => {
  await browser?.close();
  await server?.stop();
});

/**
 * Opens the demo with `query`, recording every page and page metatile the network is asked for,
 * in order; `before(page)` runs first (to add init scripts).
 */
async function openDemo(query, before = async () => {}) {
  const page = await browser.context.newPage();
  await before(page);
  const log = { errors: [], bad: [], fetches: [], other: [] };
  page.on('pageerror', (e) => log.errors.push(String(e)));
  page.on('console', (m) => m.type() === 'error' && log.errors.push(m.text()));
  page.on('response', (r) => r.status() >= 400 && log.bad.push(`${r.status()} ${r.url()}`));
  page.on('request', (r) => {
    const url = new URL(r.url());
    const path = url.pathname;
    const m = path.match(/^\/api\/v1\/textures\/\w+\/(page-metatiles|pages)\/(\d+)\/(\d+)\/(\d+)\.\w+$/);
    const layer = url.searchParams.get('layer');
    if (m) log.fetches.push(`${m[1] === 'pages' ? 'page' : 'metatile'} ${m[2]}/${m[3]}/${m[4]}${layer ? ` ${layer}` : ''}`);
    else if (/^\/api\/v1\/textures\/\w+\/tiles/.test(path)) log.other.push(path);
  });
  await page.goto(debugUrl(`${server.url}/vt.html?${query}`));
  await page.waitForFunction(() => window.vtDemo && (window.vtDemo.error || window.vtDemo.state.settled || window.vtDemo.state.done), null, {
    timeout: 120_000,
    polling: 100,
  });
  const error = await page.evaluate(() => window.vtDemo.error || window.vtDemo.state.error);
  assert.equal(error, null, 'the demo reports no error');
  return { page, log };
}

/**
 * Replays the demo's log ({ event, key }, in order): a page is requested only when it is neither
 * resident nor in flight. Returns the number of evictions.
 */
function checkNoRequestWhileHeld(events) {
  const resident = new Set();
  const inFlight = new Set();
  let evictions = 0;
  for (const { event, key, frame } of events) {
    if (event === 'request') {
      assert.ok(!resident.has(key), `page ${key} requested at frame ${frame} while resident`);
      assert.ok(!inFlight.has(key), `page ${key} requested at frame ${frame} while in flight`);
      inFlight.add(key);
    } else if (event === 'resident') {
      assert.ok(inFlight.delete(key), `page ${key} became resident without a request`);
      resident.add(key);
    } else if (event === 'drop') {
      inFlight.delete(key);
    } else if (event === 'evict') {
      assert.ok(resident.delete(key), `page ${key} evicted while not resident`);
      evictions++;
    }
  }
  return evictions;
}

/**
 * The network was asked for the pages and page metatiles the demo's log names, in order, and
 * for no batch; every page requested came by a fetch of itself or of its metatile.
 */
function checkNetwork(log, events) {
  const logged = events.filter((e) => e.event === 'fetch').map((e) => e.key);
  assert.deepEqual(log.fetches, logged, 'the demo’s log holds every fetch the network was asked for');
  assert.deepEqual(log.other, [], 'no batches');
  const side = 4; // pages of 128: 512 level pixels a side
  const fetched = new Set(logged);
  for (const { key } of events.filter((e) => e.event === 'request')) {
    const [l, x, y] = key.split('/').map(Number);
    const m = `metatile ${l}/${Math.floor(x / side)}/${Math.floor(y / side)}`;
    assert.ok(fetched.has(`page ${key}`) || fetched.has(m), `page ${key}: fetched alone or in ${m}`);
  }
  return { pages: logged.filter((k) => k.startsWith('page')).length, metatiles: logged.filter((k) => k.startsWith('metatile')).length };
}

const toLinear = (c) => {
  const v = c / 255;
  return v <= 0.04045 ? v / 12.92 : ((v + 0.055) / 1.055) ** 2.4;
};
const toSrgb = (v) => 255 * (v <= 0.0031308 ? v * 12.92 : 1.055 * v ** (1 / 2.4) - 0.055);

/** Level-0 texel coordinates where the ray through screen point (sx, sy) (GL: y up) meets the ground. */
function groundAt(c, sx, sy) {
  const [yaw, pitch] = [(c.yaw * Math.PI) / 180, (c.pitch * Math.PI) / 180];
  const tan = Math.tan((c.fov * Math.PI) / 360);
  const nx = (sx / VIEW.width) * 2 - 1;
  const ny = (sy / VIEW.height) * 2 - 1;
  const f = [Math.sin(yaw) * Math.cos(pitch), -Math.cos(yaw) * Math.cos(pitch), -Math.sin(pitch)];
  const r = [Math.cos(yaw), Math.sin(yaw), 0];
  const u = [Math.sin(yaw) * Math.sin(pitch), -Math.cos(yaw) * Math.sin(pitch), Math.cos(pitch)];
  const ax = (nx * tan * VIEW.width) / VIEW.height;
  const d = [0, 1, 2].map((i) => f[i] + ax * r[i] + ny * tan * u[i]);
  if (d[2] >= -1e-6) return null;
  const t = -c.height / d[2];
  return [c.x + t * d[0], c.y + t * d[1]];
}

/** The canvas of `page` without the overlay, decoded; also written to target/browser/`name`.png. */
async function canvasShot(page, name) {
  await page.evaluate(() => {
    document.getElementById('overlay').hidden = true;
    document.getElementById('back').hidden = true;
  });
  const png = await page.locator('#view').screenshot();
  mkdirSync(join(ROOT, 'target', 'browser'), { recursive: true });
  writeFileSync(join(ROOT, 'target', 'browser', `${name}.png`), png);
  const shot = decodePng(png);
  assert.equal(shot.width, VIEW.width);
  return shot;
}

/**
 * A grid of screen pixels on the ground at CAMERA; the texel each shows (level-0 point `p`) and
 * its level of detail, as the shader computes it: log2 of the larger one-pixel step of the texel
 * coordinates (with aniso=1), clamped to the levels there are: ⌊lod⌋ (`level`) and its fraction.
 */
function sampleGrid(maxLevel) {
  const samples = [];
  for (let py = 3; py < VIEW.height; py += 12) {
    for (let px = 5; px < VIEW.width; px += 12) {
      const sx = px + 0.5;
      const sy = VIEW.height - py - 0.5;
      const [p, pdx, pdy] = [groundAt(CAMERA, sx, sy), groundAt(CAMERA, sx + 1, sy), groundAt(CAMERA, sx, sy + 1)];
      if (!p || !pdx || !pdy) continue;
      const major = Math.max(Math.hypot(pdx[0] - p[0], pdx[1] - p[1]), Math.hypot(pdy[0] - p[0], pdy[1] - p[1]));
      const lod = Math.min(maxLevel, Math.max(0, Math.log2(major)));
      samples.push({ px, py, p, level: Math.floor(lod), toCoarser: lod - Math.floor(lod) });
    }
  }
  const levels = new Set(samples.map((s) => s.level));
  assert.ok(samples.length >= 1000 && levels.size >= 6, `${samples.length} samples over levels ${[...levels]}`);
  return samples;
}

/**
 * The texels of level `level` around level-0 point `p` filtered bilinearly, each decoded by
 * `decode(byte)` first, from `texels(level, i, j)`: the 2×2 texels from (i, j), RGBA rows.
 */
async function bilinear(p, level, texels, decode) {
  const [u, v] = [p[0] / 2 ** level - 0.5, p[1] / 2 ** level - 0.5];
  const [i, j] = [Math.floor(u), Math.floor(v)];
  const [fx, fy] = [u - i, v - j];
  const px4 = await texels(level, i, j);
  return [0, 1, 2].map((c) => {
    const at = (k) => decode(px4[k * 4 + c]);
    return (at(0) * (1 - fx) + at(1) * fx) * (1 - fy) + (at(2) * (1 - fx) + at(3) * fx) * fy;
  });
}

/** Sample `s`'s two levels blended by its fraction (`at(level)`: a level's RGB). */
async function trilinear(s, maxLevel, at) {
  const fine = await at(s.level);
  const coarse = s.level < maxLevel ? await at(s.level + 1) : fine;
  return fine.map((f, c) => f * (1 - s.toCoarser) + coarse[c] * s.toCoarser);
}

/** The server's region: the 2×2 texels of `level` from (i, j), RGBA rows. */
async function regionTexels(level, i, j) {
  const q = `level=${level}&x=${i}&y=${j}&w=2&h=2&format=rgba`;
  const r = await fetch(`${server.url}/api/v1/textures/${info.id}/region?${q}`);
  assert.equal(r.status, 200, q);
  return new Uint8Array(await r.arrayBuffer());
}

/** The largest and mean difference between `shot`'s samples and `reference(s)` (sRGB RGB). */
async function compare(shot, samples, reference) {
  let worst = 0;
  let sum = 0;
  for (const s of samples) {
    const want = await reference(s);
    for (let c = 0; c < 3; c++) {
      const d = Math.abs(shot.data[(s.py * shot.width + s.px) * 4 + c] - want[c]);
      worst = Math.max(worst, d);
      sum += d;
    }
  }
  return { worst, mean: sum / (samples.length * 3) };
}

const CAMERA_QUERY = [CAMERA.x, CAMERA.y, CAMERA.height, CAMERA.yaw, CAMERA.pitch].join(',');

test('at a fixed camera the frame equals a render from the server’s regions', async () => {
  // RGBA pages and bilinear filtering (aniso=1): the reference is exact up to the GPU's filtering.
  const { page, log } = await openDemo(`texture=${info.id}&camera=${CAMERA_QUERY}&format=rgba&aniso=1&light=off`);
  const demo = await page.evaluate(() => ({ maxLevel: window.vtDemo.pyramid.maxLevel, log: window.vtDemo.state.log }));
  const shot = await canvasShot(page, 'vt-demo-fixed');

  // Each sample's two levels, each bilinearly from the 2×2 texels of the server's region there,
  // blended by its fraction in linear light.
  const samples = sampleGrid(demo.maxLevel);
  const colour = (s) => trilinear(s, demo.maxLevel, (level) => bilinear(s.p, level, regionTexels, toLinear));
  const { worst, mean } = await compare(shot, samples, async (s) => (await colour(s)).map(toSrgb));
  const levels = [...new Set(samples.map((s) => s.level))].sort();
  console.log(`# ${samples.length} pixels over levels ${levels}: mean |Δ| ${mean.toFixed(2)}, max ${worst.toFixed(1)} of 255`);
  // Tolerance: the GPU's bilinear weights are quantized (8 fractional bits in SwiftShader, so a
  // weight is off by up to 1/512), the texel coordinates are float32 (about 0.004 texel at
  // 50,000), the GPU's derivatives are per 2×2 quad, and its sRGB decoding and the shader's
  // encoding round; where neighbouring texels differ by up to 255 these give a few levels. A page
  // from the wrong place, a border ignored or one level instead of two gives tens.
  assert.ok(mean <= 0.5, `mean difference ${mean.toFixed(2)}`);
  assert.ok(worst <= 2, `largest difference ${worst.toFixed(1)}`);

  checkNoRequestWhileHeld(demo.log);
  const fetches = checkNetwork(log, demo.log);
  assert.ok(fetches.metatiles > 0 && fetches.pages > 0, `the pinned levels come as metatiles, sparse pages alone: ${JSON.stringify(fetches)}`);
  assert.deepEqual(log.errors, []);
  assert.deepEqual(log.bad, []);
  await page.close();
});

test('lit, the frame equals the region render lit by the server’s normal pages', async () => {
  const light = [315, 45];
  const { page, log } = await openDemo(`texture=${info.id}&camera=${CAMERA_QUERY}&format=rgba&aniso=1&light=${light}`);
  const demo = await page.evaluate(() => ({ maxLevel: window.vtDemo.pyramid.maxLevel, log: window.vtDemo.state.log }));
  const shot = await canvasShot(page, 'vt-demo-lit');

  // The reference: the colour as unlit, from the regions; the normal from the server's normal
  // pages (RGBA, the page holding the point, its border supplying the neighbours across the
  // edge), decoded to [-1, 1], filtered and blended as the colour, turned into world axes (+Y up
  // the image is −y), normalized; lit by Lambert and ambient in linear light.
  const pages = new Map();
  const normalTexels = (p) => async (level, i, j) => {
    const [px, py] = [Math.floor(p[0] / 2 ** level / 128), Math.floor(p[1] / 2 ** level / 128)];
    const key = `${level}/${px}/${py}`;
    if (!pages.has(key)) {
      const r = await fetch(`${server.url}/api/v1/textures/${info.id}/pages/${key}.rgba?size=128&border=4&layer=normal`);
      assert.equal(r.status, 200, key);
      pages.set(key, new Uint8Array(await r.arrayBuffer()));
    }
    const body = pages.get(key);
    const out = new Uint8Array(16);
    for (let k = 0; k < 4; k++) {
      const [x, y] = [i + (k & 1) - px * 128 + 4, j + (k >> 1) - py * 128 + 4];
      out.set(body.subarray((y * 136 + x) * 4, (y * 136 + x) * 4 + 4), k * 4);
    }
    return out;
  };
  const [azimuth, elevation] = light.map((d) => (d * Math.PI) / 180);
  const towards = [Math.sin(azimuth) * Math.cos(elevation), -Math.cos(azimuth) * Math.cos(elevation), Math.sin(elevation)];
  const samples = sampleGrid(demo.maxLevel);
  const shades = [];
  const { worst, mean } = await compare(shot, samples, async (s) => {
    const colour = await trilinear(s, demo.maxLevel, (level) => bilinear(s.p, level, regionTexels, toLinear));
    const n = await trilinear(s, demo.maxLevel, (level) => bilinear(s.p, level, normalTexels(s.p), (b) => (b / 255) * 2 - 1));
    const world = [n[0], -n[1], n[2]];
    const length = Math.hypot(...world);
    const shade = 0.3 + 0.7 * Math.max(0, world.reduce((a, v, i) => a + (v / length) * towards[i], 0));
    shades.push(shade);
    return colour.map((c) => toSrgb(c * shade));
  });
  const flat = 0.3 + 0.7 * Math.sin(elevation);
  const spread = Math.sqrt(shades.reduce((a, v) => a + (v - flat) ** 2, 0) / shades.length);
  console.log(`# lit from ${light}: ${samples.length} pixels, mean |Δ| ${mean.toFixed(2)}, max ${worst.toFixed(1)} of 255; shade ${flat.toFixed(3)} where flat, r.m.s. ${spread.toFixed(3)} from it`);
  // The normals are not flat (else the lit frame is the unlit one times a constant, and a
  // build ignoring them would pass); the tolerance is the unlit one's, the normals' bilinear
  // weights quantized alike.
  assert.ok(spread >= 0.02, `the normals tilt the shade (r.m.s. ${spread.toFixed(3)} from flat)`);
  assert.ok(mean <= 0.5, `mean difference ${mean.toFixed(2)}`);
  assert.ok(worst <= 2, `largest difference ${worst.toFixed(1)}`);

  checkNoRequestWhileHeld(demo.log);
  const fetches = checkNetwork(log, demo.log);
  assert.ok(log.fetches.filter((f) => f.endsWith(' normal')).length * 2 === log.fetches.length, `each fetch has its normal twin: ${JSON.stringify(fetches)}`);
  assert.deepEqual(log.errors, []);
  assert.deepEqual(log.bad, []);
  await page.close();
});

/**
 * In the page, before its scripts: after every animation frame, compares the canvas with the
 * frame before (the largest channel difference of each pixel, sRGB levels) and keeps, per pixel,
 * the sum of those changes (how far it travelled) and the largest one (its largest step), and
 * per frame the share of pixels changing by more than 32.
 */
function recordFrameChanges() {
  const raf = window.requestAnimationFrame.bind(window);
  const record = { travelled: null, largest: null, frames: [] };
  window.frameChanges = record;
  let previous = null;
  window.requestAnimationFrame = (callback) =>
    raf((time) => {
      callback(time);
      const canvas = document.getElementById('view');
      const gl = canvas.getContext('webgl2');
      const pixels = new Uint8Array(canvas.width * canvas.height * 4);
      gl.readPixels(0, 0, canvas.width, canvas.height, gl.RGBA, gl.UNSIGNED_BYTE, pixels);
      if (previous?.length === pixels.length) {
        record.travelled ||= new Float64Array(pixels.length / 4);
        record.largest ||= new Float64Array(pixels.length / 4);
        let over32 = 0;
        for (let i = 0; i < pixels.length; i += 4) {
          const d = Math.max(Math.abs(pixels[i] - previous[i]), Math.abs(pixels[i + 1] - previous[i + 1]), Math.abs(pixels[i + 2] - previous[i + 2]));
          record.travelled[i / 4] += d;
          record.largest[i / 4] = Math.max(record.largest[i / 4], d);
          if (d > 32) over32++;
        }
        record.frames.push(over32 / (pixels.length / 4));
      }
      previous = pixels;
    });
}

test('while pages arrive at a fixed camera, each pixel sharpens over frames, not in one step', async () => {
  // A part of the texture no other test visits: its pages come from a cold server over frames.
  const { page, log } = await openDemo(`texture=${info.id}&camera=20000.5,30000.5,220,-30,35&format=rgba&aniso=1&light=off`, (p) => p.addInitScript(recordFrameChanges));
  const { steps, frames, streamed } = await page.evaluate(() => {
    const { travelled, largest, frames } = window.frameChanges;
    const steps = [];
    for (let i = 0; i < travelled.length; i++) if (travelled[i] >= 32) steps.push(largest[i] / travelled[i]);
    steps.sort((a, b) => a - b);
    const streamed = window.vtDemo.state.log.filter((e) => e.event === 'resident' && e.frame > 0).length;
    return { steps: [0.5, 0.9].map((q) => steps[Math.floor(q * steps.length)]).concat(steps.length), frames, streamed };
  });
  const [median, p90, refined] = steps;
  const popped = Math.max(...frames);
  console.log(
    `# ${streamed} pages streamed over ${frames.length} frames; ${refined} pixels changed by 32 or more: their largest step a median ${median.toFixed(2)} (90th percentile ${p90.toFixed(2)}) of the way; at most ${(100 * popped).toFixed(1)} % of pixels changed by more than 32 in a frame`,
  );
  assert.ok(streamed > 0 && refined >= 10_000, `pages arrived and the view sharpened (${streamed} pages, ${refined} pixels)`);
  // A pixel whose page arrives moves by 1/FADE_FRAMES of the way a frame in linear light (more
  // in sRGB where it is dark), fades of several levels overlapping; drawn at once it moves all
  // the way in one frame (1.0), or half the way twice when two levels arrive in turn.
  assert.ok(median <= 0.45, `median largest step ${median.toFixed(2)} of the way`);
  assert.ok(p90 <= 0.6, `90th percentile of the largest step ${p90.toFixed(2)} of the way`);
  assert.ok(popped <= 0.05, `${(100 * popped).toFixed(1)} % of pixels changed by more than 32 in one frame`);
  assert.deepEqual(log.errors, []);
  assert.deepEqual(log.bad, []);
  await page.close();
});

test('a fly-through through a small atlas evicts, and never asks for a page it holds', async () => {
  // 7² slots: fewer than the pages a moving view touches, so pages are evicted and asked again.
  const { page, log } = await openDemo(`texture=${info.id}&format=bc7&slots=7&frames=90`);
  const demo = await page.evaluate(() => ({ log: window.vtDemo.state.log, slots: window.vtDemo.cache.slots.length, size: window.vtDemo.cache.size }));
  // The default anisotropy, 4, filters the atlas wherever the GPU offers the extension.
  const aniso = await page.evaluate(() => {
    const { gpu, state } = window.vtDemo;
    const gl = gpu.gl;
    const ext = gl.getExtension('EXT_texture_filter_anisotropic');
    if (!ext) return { state: state.anisotropy };
    gl.bindTexture(gl.TEXTURE_2D, gpu.atlas);
    return { state: state.anisotropy, offered: gl.getParameter(ext.MAX_TEXTURE_MAX_ANISOTROPY_EXT), atlas: gl.getTexParameter(gl.TEXTURE_2D, ext.TEXTURE_MAX_ANISOTROPY_EXT) };
  });
  console.log(`# anisotropy: ${JSON.stringify(aniso)}`);
  if (aniso.offered) assert.deepEqual(aniso, { state: Math.min(4, aniso.offered), offered: aniso.offered, atlas: Math.min(4, aniso.offered) });
  else assert.equal(aniso.state, 1);
  writeFileSync(join(ROOT, 'target', 'browser', 'vt-demo-flight.png'), await page.locator('#view').screenshot());
  const evictions = checkNoRequestWhileHeld(demo.log);
  assert.ok(evictions > 0, 'the flight overflows the atlas');
  assert.ok(demo.size <= demo.slots);
  checkNetwork(log, demo.log);
  assert.deepEqual(log.errors, []);
  assert.deepEqual(log.bad, []);
  await page.close();
});
