// Shared harness for the browser tests and the measured session: a real `vtex serve` on a free
// loopback port with a fresh data directory, and Debian's Chromium driven by playwright-core.
import { spawn } from 'node:child_process';
import { mkdtempSync, rmSync, existsSync } from 'node:fs';
import { createRequire } from 'node:module';
import { tmpdir } from 'node:os';
import { dirname, join, resolve } from 'node:path';
import { createInterface } from 'node:readline';
import { fileURLToPath } from 'node:url';
import { deflateSync, inflateSync } from 'node:zlib';

export const ROOT = resolve(dirname(fileURLToPath(import.meta.url)), '..', '..');
// playwright-core is a dev dependency of client-web (one `npm ci` installs the viewer and its tests).
const require = createRequire(join(ROOT, 'client-web', 'package.json'));
const { chromium } = require('playwright-core');

export const VTEX_BIN = process.env.VTEX_BIN || join(ROOT, 'target', 'release', 'vtex');
export const CHROMIUM = process.env.CHROMIUM || '/usr/bin/chromium';
// VTEX_WEB_DIR: another build of the viewer (the bench's A/B comparisons).
export const WEB_DIR = process.env.VTEX_WEB_DIR || join(ROOT, 'client-web', 'dist');

/**
 * Starts `vtex serve` on 127.0.0.1:0 with a fresh data dir (or `dataDir`, kept at stop), serving
 * the viewer from WEB_DIR (or, with `embeddedViewer`, the copy built into the binary, as
 * deployed), with `extraArgs` and the environment variables `env`; resolves once it prints its
 * URL.
 */
export async function startServer({ extraArgs = [], env = {}, dataDir: keptDir = null, embeddedViewer = false } = {}) {
  // VTEX_URL: a server already running (e.g. nginx in front of replicas: bench/replicas).
  if (process.env.VTEX_URL) return { url: process.env.VTEX_URL, dataDir: null, stderr: () => '', async stop() {} };
  if (!existsSync(VTEX_BIN)) throw new Error(`${VTEX_BIN} not found: run cargo build --release -p vtex-server`);
  if (!embeddedViewer && !existsSync(join(WEB_DIR, 'index.html'))) throw new Error(`${WEB_DIR} not built: run npm ci && npm run build in client-web/`);
  const dataDir = keptDir || mkdtempSync(join(tmpdir(), 'vtex-browser-data-'));
  const proc = spawn(
    VTEX_BIN,
    ['serve', '--bind', '127.0.0.1:0', '--data-dir', dataDir, ...(embeddedViewer ? [] : ['--web-dir', WEB_DIR]), ...extraArgs],
    { stdio: ['ignore', 'pipe', 'pipe'], env: { ...process.env, ...env } },
  );
  let stderr = '';
  proc.stderr.on('data', (d) => {
    stderr = (stderr + d).slice(-4000);
  });
  const url = await new Promise((resolveUrl, reject) => {
    const timer = setTimeout(() => reject(new Error(`vtex did not print its URL within 120 s; stderr:\n${stderr}`)), 120_000);
    const lines = createInterface({ input: proc.stdout });
    lines.on('line', (line) => {
      const m = line.match(/^vtex listening on (http:\/\/\S+)/);
      if (m) {
        clearTimeout(timer);
        resolveUrl(m[1].replace(/\/$/, ''));
      }
    });
    proc.on('exit', (code) => {
      clearTimeout(timer);
      reject(new Error(`vtex exited with ${code} before listening; stderr:\n${stderr}`));
    });
  });
  return {
    url,
    dataDir,
    pid: proc.pid,
    stderr: () => stderr,
    async stop() {
      if (proc.exitCode === null) {
        proc.kill('SIGTERM');
        await exited(proc);
      }
      if (!keptDir) rmSync(dataDir, { recursive: true, force: true });
    },
  };
}

/** `python3 -m http.server` on a free loopback port serving `dir`: { url, stop }. */
export async function staticServer(dir) {
  const proc = spawn('python3', ['-u', '-m', 'http.server', '0', '--bind', '127.0.0.1', '--directory', dir], { stdio: ['ignore', 'pipe', 'pipe'] });
  const url = await new Promise((resolve, reject) => {
    const timer = setTimeout(() => reject(new Error('http.server did not start within 30 s')), 30_000);
    createInterface({ input: proc.stdout }).on('line', (line) => {
      const m = line.match(/port (\d+)/);
      if (m) {
        clearTimeout(timer);
        resolve(`http://127.0.0.1:${m[1]}`);
      }
    });
    proc.on('exit', (code) => reject(new Error(`http.server exited with ${code}`)));
  });
  return { url, stop: () => (proc.kill('SIGTERM'), exited(proc)) };
}

/** Resolves once `proc` has exited, killing it if it is still running after `ms`. */
export function exited(proc, ms = 5000) {
  return new Promise((r) => {
    if (proc.exitCode !== null) return r();
    const t = setTimeout(() => {
      proc.kill('SIGKILL');
      r();
    }, ms);
    proc.once('exit', () => {
      clearTimeout(t);
      r();
    });
  });
}

/** Chromium's flags for the tests and the bench: headless, software only, no background traffic. */
export const CHROMIUM_ARGS = [
  '--headless',
  '--no-sandbox',
  '--disable-gpu',
  '--disable-quic',
  '--no-first-run',
  '--disable-background-networking',
  '--disable-component-update',
  '--disable-sync',
  '--force-color-profile=srgb',
];

/** Launches headless Chromium with a fresh profile (so a fresh, empty HTTP cache). */
export async function launchBrowser({ width = 1280, height = 800 } = {}) {
  const profile = mkdtempSync(join(tmpdir(), 'vtex-chromium-'));
  const context = await chromium.launchPersistentContext(profile, {
    executablePath: CHROMIUM,
    headless: true,
    viewport: { width, height },
    deviceScaleFactor: 1,
    args: CHROMIUM_ARGS,
  });
  return {
    context,
    profile,
    async close() {
      await context.close();
      rmSync(profile, { recursive: true, force: true });
    },
  };
}

/**
 * What most browser test files start with: a server with the demos, a browser (`browserSize`,
 * launchBrowser's default if none) and the server's texture list. Close with closeSession.
 */
export async function startSession({ browserSize } = {}) {
  const server = await startServer();
  const browser = await launchBrowser(browserSize);
  const { textures } = await (await fetch(`${server.url}/api/v1/textures`)).json();
  return { server, browser, textures };
}

/** Closes what startSession started (either may be missing if it failed part-way). */
export async function closeSession({ server, browser }) {
  await browser?.close();
  await server?.stop();
}

/**
 * `url` (a page of the viewer's) with the `debug` parameter, which makes the viewer and the VT
 * demo expose their hooks (`window.vtexViewer`, `window.vtDemo`; client-web/src/shared/debug.js).
 */
export function debugUrl(url) {
  return `${url}${url.includes('?') ? '&' : '?'}debug`;
}

/**
 * Opens `url` (with its hooks: debugUrl) in a new page that records console errors, page
 * errors, failed requests and every request made, so tests can assert on all of them.
 */
export async function openViewer(context, url) {
  const page = await context.newPage();
  const log = { errors: [], requests: [], failed: [], badResponses: [] };
  page.on('console', (m) => {
    if (m.type() === 'error') log.errors.push(m.text());
  });
  page.on('pageerror', (e) => log.errors.push(String(e)));
  page.on('request', (r) => log.requests.push(r.url()));
  page.on('requestfailed', (r) => log.failed.push(`${r.url()}: ${r.failure()?.errorText}`));
  page.on('response', (r) => {
    if (r.status() >= 400) log.badResponses.push(`${r.status()} ${r.url()}`);
  });
  await page.goto(debugUrl(url));
  await page.waitForFunction(() => window.vtexViewer && window.vtexViewer.state.item);
  return { page, log };
}

/** In the page: whether the view has settled and every tile it needs is loaded and drawn. */
export function viewerIdle() {
  const v = window.vtexViewer;
  const item = v.state.item;
  const vp = v.viewer.viewport;
  const settled = vp.getZoom(true) === vp.getZoom(false) && vp.getCenter(true).equals(vp.getCenter(false));
  return settled && item && item.getFullyLoaded() && !v.viewer.world.needsDraw() && v.state.pending === null;
}

/** Resolves when every tile the current view needs is loaded and drawn. */
export async function waitForIdle(page, timeout = 60_000) {
  // Let OpenSeadragon run at least one update after whatever the caller just did.
  await page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
  await page.waitForFunction(viewerIdle, null, { timeout, polling: 50 });
}

/**
 * How much a screenshot shows: colours at 5 bits a channel that each cover at least 0.1 % of
 * its pixels (noise adds rare colours, not common ones), and the standard deviation of luma.
 */
export function structure(shot) {
  const counts = new Map();
  let sum = 0;
  let sum2 = 0;
  const n = shot.width * shot.height;
  for (let i = 0; i < shot.data.length; i += 4) {
    const [r, g, b] = shot.data.subarray(i, i + 3);
    const key = ((r >> 3) << 10) | ((g >> 3) << 5) | (b >> 3);
    counts.set(key, (counts.get(key) || 0) + 1);
    const luma = 0.2126 * r + 0.7152 * g + 0.0722 * b;
    sum += luma;
    sum2 += luma * luma;
  }
  const colours = [...counts.values()].filter((c) => c >= n / 1000).length;
  return { colours, sd: Math.sqrt(Math.max(0, sum2 / n - (sum / n) ** 2)) };
}

/** The central half (each way) of the view, away from the controls and the navigator. */
export async function viewCentre(page) {
  const box = await page.locator('#osd').boundingBox();
  const clip = { x: Math.round(box.x + box.width / 4), y: Math.round(box.y + box.height / 4), width: Math.round(box.width / 2), height: Math.round(box.height / 2) };
  return decodePng(await page.screenshot({ clip }));
}

/** Where level-0 pixel (x, y)'s top-left corner is, in viewer-element and page coordinates. */
export async function screenPointOf(page, x, y) {
  return page.evaluate(
    ([x, y]) => {
      const { viewer, state } = window.vtexViewer;
      const p = state.item.imageToViewerElementCoordinates(new OpenSeadragon.Point(x, y));
      const r = viewer.element.getBoundingClientRect();
      return { ex: p.x, ey: p.y, px: p.x + r.left, py: p.y + r.top };
    },
    [x, y],
  );
}

/** Sets the view (zoom in screen px per level-0 px, centre in level-0 px) and moves it by a
 * fraction of a screen pixel so that level-0 pixel (x, y) starts on a whole screen pixel. */
export async function setAlignedView(page, zoom, x, y) {
  await page.evaluate(
    ([zoom, x, y]) => {
      const { viewer, state, setView } = window.vtexViewer;
      setView({ zoom, x, y }, true);
      viewer.viewport.applyConstraints(true);
      const p = state.item.imageToViewerElementCoordinates(new OpenSeadragon.Point(x, y));
      const r = viewer.element.getBoundingClientRect();
      const px = p.x + r.left;
      const py = p.y + r.top;
      const d = new OpenSeadragon.Point(px - Math.round(px), py - Math.round(py));
      viewer.viewport.panBy(viewer.viewport.deltaPointsFromPixels(d, true), true);
    },
    [zoom, x, y],
  );
  await waitForIdle(page);
}

/**
 * Every tile asked for in `urls`, parsed: single-tile URLs, each tile listed by a batched
 * request (`/tiles?format=…&tiles=L/x/y,…`), and metatiles (what the viewer sends), with
 * `metatile: true` and the block's coordinates as x and y.
 */
export function tileRequests(urls) {
  const out = [];
  for (const u of urls) {
    const url = new URL(u);
    const m = url.pathname.match(/^\/api\/v1\/textures\/([^/]+)\/tiles\/(\d+)\/(\d+)\/(\d+)\.(\w+)$/);
    if (m) out.push({ id: m[1], level: +m[2], x: +m[3], y: +m[4], format: m[5], frame: url.searchParams.get('frame') });
    const meta = url.pathname.match(/^\/api\/v1\/textures\/([^/]+)\/metatiles\/(\d+)\/(\d+)\/(\d+)\.(\w+)$/);
    if (meta) {
      const [, id, level, x, y, format] = meta;
      out.push({ id, level: +level, x: +x, y: +y, format, frame: url.searchParams.get('frame'), metatile: true });
    }
    const b = url.pathname.match(/^\/api\/v1\/textures\/([^/]+)\/tiles$/);
    if (b) {
      for (const t of url.searchParams.get('tiles').split(',')) {
        const [level, x, y] = t.split('/').map(Number);
        out.push({ id: b[1], level, x, y, format: url.searchParams.get('format'), frame: url.searchParams.get('frame'), batch: true });
      }
    }
  }
  return out;
}

/** The server's tile as raw RGBA (the `.rgba` format, sized by X-Vtex-Width/Height). */
export async function fetchServerTile(serverUrl, info, level, tx, ty, frame) {
  const q = frame === undefined ? '' : `?frame=${frame}`;
  const r = await fetch(`${serverUrl}/api/v1/textures/${info.id}/tiles/${level}/${tx}/${ty}.rgba${q}`);
  if (r.status !== 200) throw new Error(`tile ${level}/${tx}/${ty} of ${info.name}: HTTP ${r.status}`);
  return { width: +r.headers.get('x-vtex-width'), height: +r.headers.get('x-vtex-height'), data: Buffer.from(await r.arrayBuffer()) };
}

/**
 * Checks that every pixel of the screen box `clip` shows exactly the server's texel under its
 * centre at `level` (0 unless given; no seams, no stretched tiles, no smoothing): `at` maps
 * level-`level` point (x, y) to screen (ax, ay) at sx × sy screen pixels per texel. Pixel
 * centres within 1 % of a texel edge, which may round either way, are skipped. A pixel beyond
 * the level's edge must show `beyond` ([r, g, b], what is behind a transparent layer) when it
 * is given, and is otherwise skipped. Returns the pixels compared, the number of tiles they
 * came from, and the pixels found beyond the edge.
 */
export async function compareScreenToTexels(page, serverUrl, info, x, y, at, clip, { level = 0, beyond } = {}) {
  const shot = decodePng(await page.screenshot({ clip }));
  const ts = info.tile_size;
  const [lw, lh] = [Math.ceil(info.width / 2 ** level), Math.ceil(info.height / 2 ** level)];
  const tiles = new Map();
  let compared = 0;
  let outside = 0;
  for (let j = 0; j < clip.height; j++) {
    for (let i = 0; i < clip.width; i++) {
      const ix = x + (clip.x + i + 0.5 - at.ax) / at.sx;
      const iy = y + (clip.y + j + 0.5 - at.ay) / at.sy;
      const p = (j * clip.width + i) * 4;
      if (ix < 0 || iy < 0 || ix >= lw || iy >= lh) {
        if (!beyond) continue;
        for (let c = 0; c < 3; c++) {
          if (shot.data[p + c] !== beyond[c]) {
            throw new Error(`screen (${clip.x + i}, ${clip.y + j}), beyond level ${level}'s ${lw} × ${lh} texels, shows ${shot.data[p + c]} in channel ${c}, not ${beyond[c]}`);
          }
        }
        outside++;
        continue;
      }
      const fx = ix - Math.floor(ix);
      const fy = iy - Math.floor(iy);
      if (fx < 0.01 || fx > 0.99 || fy < 0.01 || fy > 0.99) continue;
      const [tx, ty] = [Math.floor(ix), Math.floor(iy)];
      const key = `${Math.floor(tx / ts)},${Math.floor(ty / ts)}`;
      if (!tiles.has(key)) tiles.set(key, await fetchServerTile(serverUrl, info, level, Math.floor(tx / ts), Math.floor(ty / ts)));
      const tile = tiles.get(key);
      const t = ((ty % ts) * tile.width + (tx % ts)) * 4;
      for (let c = 0; c < 3; c++) {
        if (shot.data[p + c] !== tile.data[t + c]) {
          throw new Error(`screen (${clip.x + i}, ${clip.y + j}) shows ${shot.data[p + c]} in channel ${c}, texel (${tx}, ${ty}) of level ${level} is ${tile.data[t + c]}`);
        }
      }
      compared++;
    }
  }
  return { compared, tiles: tiles.size, beyond: outside };
}

/**
 * Compares a `size`² patch of the screen whose top-left shows level-`level` pixel (lx, ly) at
 * 1:1 against the server's tile. Returns the largest channel difference (alpha ignored).
 */
export async function compareScreenToServerTile(page, serverUrl, info, level, lx, ly, size = 32, frame) {
  const ts = info.tile_size;
  const tile = await fetchServerTile(serverUrl, info, level, Math.floor(lx / ts), Math.floor(ly / ts), frame);
  return compareScreenToImage(page, tile, lx % ts, ly % ts, level, lx, ly, size);
}

/**
 * Compares a `size`² patch of the screen whose top-left shows level-`level` pixel (lx, ly) at
 * 1:1 against `image` ({ width, height, data: RGBA rows }) from its pixel (ox, oy). Returns the
 * largest channel difference (alpha ignored).
 */
export async function compareScreenToImage(page, image, ox, oy, level, lx, ly, size = 32) {
  if (!(ox + size <= image.width && oy + size <= image.height)) throw new Error('the patch is not inside the image');
  const s = 2 ** level;
  const at = await screenPointOf(page, lx * s, ly * s);
  const shot = decodePng(await page.screenshot({ clip: { x: Math.round(at.px), y: Math.round(at.py), width: size, height: size } }));
  let worst = 0;
  for (let j = 0; j < size; j++) {
    for (let i = 0; i < size; i++) {
      const a = (j * size + i) * 4;
      const b = ((oy + j) * image.width + ox + i) * 4;
      for (let c = 0; c < 3; c++) worst = Math.max(worst, Math.abs(shot.data[a + c] - image.data[b + c]));
    }
  }
  return worst;
}

/** Decodes an 8-bit, non-interlaced RGB or RGBA PNG (what Chromium's screenshots are). */
export function decodePng(buf) {
  const sig = '89504e470d0a1a0a';
  if (buf.subarray(0, 8).toString('hex') !== sig) throw new Error('not a PNG');
  let off = 8;
  let width = 0;
  let height = 0;
  let colorType = 0;
  const idat = [];
  while (off < buf.length) {
    const len = buf.readUInt32BE(off);
    const type = buf.toString('latin1', off + 4, off + 8);
    const data = buf.subarray(off + 8, off + 8 + len);
    if (type === 'IHDR') {
      width = data.readUInt32BE(0);
      height = data.readUInt32BE(4);
      if (data[8] !== 8 || data[12] !== 0) throw new Error('only 8-bit non-interlaced PNGs');
      colorType = data[9];
    } else if (type === 'IDAT') idat.push(data);
    else if (type === 'IEND') break;
    off += 12 + len;
  }
  const channels = { 2: 3, 6: 4 }[colorType];
  if (!channels) throw new Error(`PNG colour type ${colorType} not supported`);
  const raw = inflateSync(Buffer.concat(idat));
  const stride = width * channels;
  const out = Buffer.alloc(width * height * 4);
  let prev = Buffer.alloc(stride);
  for (let y = 0; y < height; y++) {
    const filter = raw[y * (stride + 1)];
    const line = Buffer.from(raw.subarray(y * (stride + 1) + 1, (y + 1) * (stride + 1)));
    for (let i = 0; i < stride; i++) {
      const a = i >= channels ? line[i - channels] : 0;
      const b = prev[i];
      const c = i >= channels ? prev[i - channels] : 0;
      let p;
      if (filter === 0) p = 0;
      else if (filter === 1) p = a;
      else if (filter === 2) p = b;
      else if (filter === 3) p = (a + b) >> 1;
      else if (filter === 4) {
        const pa = Math.abs(b - c);
        const pb = Math.abs(a - c);
        const pc = Math.abs(a + b - 2 * c);
        p = pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
      } else throw new Error(`bad PNG filter ${filter}`);
      line[i] = (line[i] + p) & 255;
    }
    for (let x = 0; x < width; x++) {
      out[(y * width + x) * 4] = line[x * channels];
      out[(y * width + x) * 4 + 1] = line[x * channels + 1];
      out[(y * width + x) * 4 + 2] = line[x * channels + 2];
      out[(y * width + x) * 4 + 3] = channels === 4 ? line[x * channels + 3] : 255;
    }
    prev = line;
  }
  return { width, height, data: out };
}

const CRC_TABLE = Array.from({ length: 256 }, (_, n) => {
  let c = n;
  for (let k = 0; k < 8; k++) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
  return c >>> 0;
});

function crc32(buf) {
  let c = 0xffffffff;
  for (const b of buf) c = CRC_TABLE[(c ^ b) & 255] ^ (c >>> 8);
  return (c ^ 0xffffffff) >>> 0;
}

/** Encodes RGBA rows (`data`, width × height × 4 bytes) as an 8-bit RGBA PNG. */
export function encodePng(width, height, data) {
  const chunk = (type, body) => {
    const head = Buffer.alloc(8);
    head.writeUInt32BE(body.length, 0);
    head.write(type, 4, 'latin1');
    const crc = Buffer.alloc(4);
    crc.writeUInt32BE(crc32(Buffer.concat([head.subarray(4), body])), 0);
    return Buffer.concat([head, body, crc]);
  };
  const ihdr = Buffer.alloc(13);
  ihdr.writeUInt32BE(width, 0);
  ihdr.writeUInt32BE(height, 4);
  ihdr.set([8, 6, 0, 0, 0], 8);
  const raw = Buffer.alloc(height * (width * 4 + 1));
  for (let y = 0; y < height; y++) Buffer.from(data.buffer, data.byteOffset + y * width * 4, width * 4).copy(raw, y * (width * 4 + 1) + 1);
  const sig = Buffer.from('89504e470d0a1a0a', 'hex');
  return Buffer.concat([sig, chunk('IHDR', ihdr), chunk('IDAT', deflateSync(raw)), chunk('IEND', Buffer.alloc(0))]);
}
