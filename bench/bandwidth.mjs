// The bandwidth experiment of the Chaos Mosaic paper (§3.3: ship the encoding, let the client
// synthesize): one fixed, scripted pan-and-zoom session in headless Chromium over the flagship
// 100k demo of every model, once per mode — server tiles as png, webp, jpg and rgba, and client
// synthesis (`?synth=client`: the encoding and the WebAssembly module, no tile requests) — under
// loopback and under Chromium's network emulation (10 Mbit/s with 40 ms RTT, and DevTools'
// "Slow 4G" preset). Writes docs/bandwidth.md (tables), docs/bandwidth.svg (plot) and the raw
// figures as JSON.
//
//   flock /tmp/vtex-bench.lock node bench/bandwidth.mjs [--models chaos-mosaic,lcm]
//        [--modes png,webp,jpg,rgba,client] [--profiles loopback,10mbit,slow4g]
//        [--slow-modes jpg,client] [--cap 150]
//        [--samples 6] [--out docs] [--json bench/results/bandwidth.json]
//   node bench/bandwidth.mjs --render bench/results/bandwidth.json   (tables and plot again)
//
// (It takes the lock itself when started without it.) Needs the viewer built with the modules
// (scripts/build-wasm, then client-web's `npm run build`: dist/vtex_synth_<model>.wasm), then target/release/vtex built (it embeds the viewer, whose
// files it serves as deployed: brotli copies from the viewer's build), and Debian's Chromium.
//
// For each session: bytes on the wire (DevTools' encodedDataLength of the page's requests — the
// viewer's code, the texture list, the encoding, the module — plus the Resource Timing
// transferSize of the tile batches, which the viewer's tile Worker fetches), requests, the time
// from navigation to the first complete view (every tile of the view drawn) and to the end of
// the session, the CPU time of every Chromium process (client) and of `vtex serve` (server).
// Every session has a fresh server (empty tile cache) and a fresh browser profile (empty HTTP
// cache), so the module and the viewer's code are fetched once in each.
import { spawnSync } from 'node:child_process';
import { readFileSync, readdirSync, writeFileSync, mkdirSync, mkdtempSync, rmSync } from 'node:fs';
import { cpus, loadavg, tmpdir } from 'node:os';
import { dirname, join } from 'node:path';
import { parseArgs } from 'node:util';
import { ROOT, CHROMIUM, launchBrowser, startServer, waitForIdle } from '../tests/browser/lib.mjs';
import { moduleFile } from '../client-web/src/shared/vtex-synth.js';

const LOCK = '/tmp/vtex-bench.lock';
if (!process.env.VTEX_BENCH_LOCKED && !process.argv.includes('--render')) {
  const r = spawnSync('flock', [LOCK, process.execPath, ...process.argv.slice(1)], {
    stdio: 'inherit',
    env: { ...process.env, VTEX_BENCH_LOCKED: '1' },
  });
  process.exit(r.status ?? 1);
}

const { values: args } = parseArgs({
  options: {
    models: { type: 'string', default: 'chaos-mosaic,lcm,patterns,order-independent,cascade' },
    modes: { type: 'string', default: 'png,webp,jpg,rgba,client' },
    profiles: { type: 'string', default: 'loopback,10mbit,slow4g' },
    // Modes run under the slow mobile profile: the smallest tile format and client synthesis
    // (the lossless formats take minutes a session there).
    'slow-modes': { type: 'string', default: 'jpg,client' },
    // A session not over after this many seconds is cut there (and said so).
    cap: { type: 'string', default: '150' },
    // Tiles sampled per level and format to extrapolate the explicit pyramid's size.
    samples: { type: 'string', default: '6' },
    width: { type: 'string', default: '1024' },
    height: { type: 'string', default: '640' },
    out: { type: 'string', default: join(ROOT, 'docs') },
    json: { type: 'string', default: join(ROOT, 'bench', 'results', 'bandwidth.json') },
    // Writes the tables and the plot again from a JSON of an earlier run, running nothing.
    render: { type: 'string' },
  },
});
const MODES = args.modes.split(',');
const modesFor = (profile) => (profile === 'slow4g' ? args['slow-modes'].split(',').filter((m) => MODES.includes(m)) : MODES);
const CAP_MS = Number(args.cap) * 1000;
const SIZE = { width: Number(args.width), height: Number(args.height) };

/** Network profiles: Chromium's emulation (Network.emulateNetworkConditions), null = loopback. */
const PROFILES = {
  loopback: { label: 'loopback', conditions: null },
  '10mbit': { label: '10 Mbit/s, 40 ms RTT', conditions: { latency: 40, downloadThroughput: 10e6 / 8, uploadThroughput: 10e6 / 8 } },
  // DevTools' "Slow 4G" preset (Lighthouse's mobile throttling: 1.6 Mbit/s, 750 kbit/s, 150 ms
  // RTT, scaled as DevTools scales it for request-level emulation).
  slow4g: { label: 'Slow 4G (1.44 Mbit/s, 562.5 ms)', conditions: { latency: 562.5, downloadThroughput: (1.6e6 * 0.9) / 8, uploadThroughput: (750e3 * 0.9) / 8 } },
};
const profiles = args.profiles.split(',').map((p) => {
  if (!PROFILES[p]) throw new Error(`--profiles: unknown ${p}; known: ${Object.keys(PROFILES)}`);
  return p;
});

/** The flagship 100k demo of each model (by name; the largest of the model if renamed). */
const FLAGSHIPS = {
  'chaos-mosaic': 'Pebbles — chaos mosaic 100k',
  lcm: 'LCM pebbles 100k',
  patterns: 'Patterns: aperiodic tiling of 16 patterns (100032²)',
  'order-independent': 'Order-independent B — pebbles',
  cascade: 'Cascade A — logistic ripples',
};

/**
 * The session: views as (zoom in screen px per level-0 px, centre as fractions of the texture),
 * each applied at once after the previous one is complete. It zooms from the whole texture down
 * to level 0, pans there, jumps, zooms out and in elsewhere: 13 views after the first.
 */
const SESSION = [
  [1 / 64, 0.5, 0.5],
  [1 / 8, 0.5, 0.5],
  [1, 0.5, 0.5],
  [1, 0.5 + 800e-5, 0.5],
  [1, 0.5 + 800e-5, 0.5 + 500e-5],
  [1, 0.5 - 400e-5, 0.5 + 500e-5],
  [1 / 4, 0.3, 0.7],
  [1, 0.3, 0.7],
  [1, 0.3 + 1000e-5, 0.7],
  [1 / 32, 0.8, 0.2],
  [2, 0.8, 0.2],
  [1 / 2, 0.1, 0.1],
  [1 / 16, 0.1, 0.1],
];

const sum = (xs) => xs.reduce((a, b) => a + b, 0);
const TICK = 100; // USER_HZ: /proc/<pid>/stat counts CPU in 1/100 s on Linux

/** CPU seconds (user + system) of `pid`, or 0 when it is gone. */
function cpuOf(pid) {
  try {
    const stat = readFileSync(`/proc/${pid}/stat`, 'utf8');
    const fields = stat.slice(stat.lastIndexOf(')') + 2).split(' ');
    return (Number(fields[11]) + Number(fields[12])) / TICK;
  } catch {
    return 0;
  }
}

/** CPU seconds of every process of the Chromium using `profile` (it and its descendants). */
function chromiumCpu(profile) {
  const procs = [];
  for (const name of readdirSync('/proc')) {
    if (!/^\d+$/.test(name)) continue;
    try {
      const stat = readFileSync(`/proc/${name}/stat`, 'utf8');
      const ppid = Number(stat.slice(stat.lastIndexOf(')') + 2).split(' ')[1]);
      const cmd = readFileSync(`/proc/${name}/cmdline`, 'utf8');
      procs.push({ pid: Number(name), ppid, mine: cmd.includes(profile) });
    } catch {
      // the process ended while we looked
    }
  }
  const ours = new Set(procs.filter((p) => p.mine).map((p) => p.pid));
  for (let grew = true; grew; ) {
    grew = false;
    for (const p of procs) if (!ours.has(p.pid) && ours.has(p.ppid)) grew = ours.add(p.pid);
  }
  return sum([...ours].map(cpuOf));
}

/** What a page request is, by its URL. */
function category(url) {
  const path = new URL(url).pathname;
  if (path.endsWith('.wasm')) return 'module';
  if (/\/encoding$/.test(path)) return 'encoding';
  if (/^\/api\/v1\/textures\/[^/]+\/tiles/.test(path)) return 'tiles';
  return 'viewer';
}

/** Runs the session on `info` in `mode` under `profile`. */
async function session(dataDir, info, mode, profile) {
  const server = await startServer({ dataDir, embeddedViewer: true });
  const browser = await launchBrowser(SIZE);
  const result = { model: info.model, mode, profile, views: 0, complete: false };
  try {
    const page = await browser.context.newPage();
    const cdp = await browser.context.newCDPSession(page);
    await cdp.send('Network.enable');
    const conditions = PROFILES[profile].conditions;
    if (conditions) await cdp.send('Network.emulateNetworkConditions', { offline: false, ...conditions });
    const urls = new Map();
    const bytes = { viewer: 0, module: 0, encoding: 0, tiles: 0 };
    let requests = 0;
    cdp.on('Network.requestWillBeSent', (e) => urls.set(e.requestId, e.request.url));
    cdp.on('Network.loadingFinished', (e) => {
      const url = urls.get(e.requestId);
      if (!url || !/^http/.test(url)) return;
      bytes[category(url)] += e.encodedDataLength;
      requests++;
    });
    const cpu0 = { client: chromiumCpu(browser.profile), server: cpuOf(server.pid) };
    const query = mode === 'client' ? 'synth=client' : `format=${mode}`;
    const t0 = performance.now();
    const left = () => Math.max(1, CAP_MS - (performance.now() - t0));
    try {
      await page.goto(`${server.url}/?texture=${info.id}&${query}&debug`, { timeout: left() });
      await page.waitForFunction(() => window.vtexViewer && window.vtexViewer.state.item, null, { timeout: left() });
      await waitForIdle(page, left());
      result.firstViewMs = performance.now() - t0;
      for (const [zoom, fx, fy] of SESSION) {
        await page.evaluate(([zoom, x, y]) => window.vtexViewer.setView({ zoom, x, y }, true), [zoom, fx * info.width, fy * info.height]);
        await waitForIdle(page, left());
        result.views++;
      }
      result.complete = true;
    } catch (e) {
      if (e.name !== 'TimeoutError') throw e;
    }
    result.endMs = performance.now() - t0;
    const stats = await page.evaluate(() => window.vtexViewer?.stats.snapshot() ?? null);
    result.cpu = { client: chromiumCpu(browser.profile) - cpu0.client, server: cpuOf(server.pid) - cpu0.server };
    // Tile batches come from the viewer's Worker, whose requests the page's DevTools session
    // does not see: their Resource Timing transferSize, as the viewer counts it.
    if (mode !== 'client' && stats) bytes.tiles += stats.wireBytes;
    result.bytes = bytes;
    result.total = sum(Object.values(bytes));
    result.requests = requests + (mode !== 'client' && stats ? stats.batches : 0);
    result.tiles = stats ? stats.loaded : 0;
    result.failed = stats ? stats.failed : 0;
  } finally {
    await browser.close();
    await server.stop();
  }
  return result;
}

/** A deterministic spread of `k` of the `n` tiles of a level, as (x, y). */
function sampleTiles(nx, ny, k) {
  const out = [];
  for (let i = 0; i < Math.min(k, nx * ny); i++) {
    const t = Math.floor(((i + 0.5) / Math.min(k, nx * ny)) * nx * ny * 0.999983) + ((i * 7919) % 13);
    const idx = Math.min(nx * ny - 1, t);
    out.push([idx % nx, Math.floor(idx / nx)]);
  }
  return out;
}

/**
 * The explicit texture's size, extrapolated: the mean size of sampled tiles of each level as PNG
 * and as JPEG times the level's tile count, summed over the pyramid; with the raw 24-bit size.
 */
async function explicitSize(dataDir, info) {
  const server = await startServer({ dataDir });
  try {
    const k = Number(args.samples);
    const est = { png: 0, jpg: 0, sampled: 0 };
    for (let level = 0; level < info.levels; level++) {
      const w = Math.ceil(info.width / 2 ** level);
      const h = Math.ceil(info.height / 2 ** level);
      const nx = Math.ceil(w / info.tile_size);
      const ny = Math.ceil(h / info.tile_size);
      const tiles = sampleTiles(nx, ny, k);
      for (const format of ['png', 'jpg']) {
        const sizes = [];
        for (const [x, y] of tiles) {
          const r = await fetch(`${server.url}/api/v1/textures/${info.id}/tiles/${level}/${x}/${y}.${format}`);
          sizes.push((await r.arrayBuffer()).byteLength);
        }
        est[format] += (sum(sizes) / sizes.length) * nx * ny;
      }
      est.sampled += tiles.length;
    }
    return { ...est, raw24: info.width * info.height * 3 };
  } finally {
    await server.stop();
  }
}

// ---------------------------------------------------------------------------------------------
// Formatting

const MB = (n) => (n >= 1e9 ? `${(n / 1e9).toFixed(2)} GB` : n >= 1e6 ? `${(n / 1e6).toFixed(2)} MB` : `${(n / 1e3).toFixed(1)} kB`);
const sec = (ms) => (ms === undefined ? '–' : `${(ms / 1000).toFixed(2)} s`);
const times = (a, b) => (b > 0 ? `${(a / b).toFixed(a / b >= 100 ? 0 : 1)}×` : '–');

/** The paper's storage arithmetic (§3.1–3.3) beside the 100k chaos mosaic's encoding. */
function paperSection(mosaic) {
  const m = 5000;
  const n = 128;
  const blocks = (12 * m * m) / (n * n);
  const sample = n * n * 3;
  const lines = [
    '## The paper\'s arithmetic',
    '',
    `- One random block per tile costs 12 bytes, so an m × m texture from an n × n sample needs 12·m²/n² bytes of blocks: for m = ${m}, n = ${n}, ${Math.round(blocks).toLocaleString('en-US')} B; with the 24-bit sample (${sample.toLocaleString('en-US')} B) ${Math.round(blocks + sample).toLocaleString('en-US')} B — the paper's "about 67 Kb".`,
    `- The explicit ${m}² texture is ${(m * m * 3).toLocaleString('en-US')} B, n²/4 = ${((m * m * 3) / blocks).toFixed(0)} times the blocks (the paper's "4,000 times smaller"), ${((m * m * 3) / (blocks + sample)).toFixed(0)} times blocks and sample.`,
  ];
  if (mosaic) {
    const mm = mosaic.width;
    const nn = mm / 625;
    lines.push(
      `- The 100k chaos mosaic here (m = ${mm.toLocaleString('en-US')}, n = ${nn}, two blocks per tile): 12·m²/n²·2 = ${MB((12 * mm * mm * 2) / (nn * nn))} of blocks if they were stored; vtex derives them from a seed and stores the sample as PNG, so the whole encoding is ${mosaic.encoding_bytes.toLocaleString('en-US')} B, ${Math.round(mosaic.explicit_bytes / mosaic.encoding_bytes).toLocaleString('en-US')} times smaller than the explicit 24-bit level 0 (${MB(mosaic.explicit_bytes)}).`,
    );
  }
  return lines.join('\n');
}

function modelSection(model, info, explicit, rows) {
  const out = [`### ${model}: “${info.name}” (${info.width.toLocaleString('en-US')}²)`, ''];
  out.push(
    `Encoding ${info.encoding_bytes.toLocaleString('en-US')} B. Explicit texture, extrapolated from ${explicit.sampled} sampled tiles a format over its ${info.levels} levels: PNG pyramid ≈ ${MB(explicit.png)}, JPEG pyramid ≈ ${MB(explicit.jpg)}; level 0 as raw 24-bit ${MB(explicit.raw24)}.`,
    '',
    '| mode | network | on the wire | tiles | module | encoding | viewer code | requests | first complete view | end of session | client CPU | server CPU |',
    '|---|---|---|---|---|---|---|---|---|---|---|---|',
  );
  for (const r of rows) {
    const end = r.complete ? sec(r.endMs) : `cut at ${sec(r.endMs)} (${r.views}/${SESSION.length} views)`;
    out.push(
      `| ${r.mode} | ${PROFILES[r.profile].label} | ${MB(r.total)} | ${MB(r.bytes.tiles)} | ${MB(r.bytes.module)} | ${MB(r.bytes.encoding)} | ${MB(r.bytes.viewer)} | ${r.requests} | ${sec(r.firstViewMs)} | ${end} | ${r.cpu.client.toFixed(1)} s | ${r.cpu.server.toFixed(1)} s |`,
    );
  }
  return out.join('\n');
}

/** Per model: the best tile format's session bytes against client mode's, and the first views at 10 Mbit/s. */
function summary(byModel) {
  const out = [
    '| model | best tile format: session bytes | client mode: session bytes (module + encoding + viewer) | ratio | without the module (cached) | tile bytes : encoding | first complete view at 10 Mbit/s, best tile format / client | end of session at 10 Mbit/s, best tile format / client | views for 100× (extrapolated) | explicit JPEG pyramid : encoding |',
    '|---|---|---|---|---|---|---|---|---|---|',
  ];
  for (const [model, { rows, info, explicit }] of byModel) {
    const ref = rows.filter((r) => r.profile === (rows.some((x) => x.profile === '10mbit') ? '10mbit' : rows[0].profile));
    const server = ref.filter((r) => r.mode !== 'client' && r.complete).sort((a, b) => a.total - b.total)[0];
    const client = ref.find((r) => r.mode === 'client');
    if (!server || !client) continue;
    const fastest = rows
      .filter((r) => r.profile === '10mbit' && r.mode !== 'client' && r.firstViewMs !== undefined)
      .sort((a, b) => a.firstViewMs - b.firstViewMs)[0];
    const clientFirst = rows.find((r) => r.profile === '10mbit' && r.mode === 'client');
    const serverEnd = rows.find((r) => r.profile === '10mbit' && r.mode === server.mode);
    out.push(
      `| ${model} | ${server.mode}: ${MB(server.total)} | ${MB(client.total)} | ${times(server.total, client.total)} | ${times(server.total, client.total - client.bytes.module)} | ${times(server.bytes.tiles, client.bytes.encoding)} | ${fastest ? `${fastest.mode} ${sec(fastest.firstViewMs)}` : '–'} / ${sec(clientFirst?.firstViewMs)} | ${serverEnd ? `${serverEnd.mode} ${sec(serverEnd.endMs)}` : '–'} / ${sec(clientFirst?.endMs)} | ${viewsFor100(server, client)} | ${times(explicit.jpg, info.encoding_bytes)} |`,
    );
  }
  return out.join('\n');
}

/**
 * How long a session must be for client mode to move 100× fewer bytes than `server`: the
 * server's tile bytes grow with every view (at this session's mean per view), client mode's
 * bytes are paid once (module, encoding, viewer code). Views, rounded up.
 */
function viewsFor100(server, client) {
  const perView = server.bytes.tiles / (SESSION.length + 1);
  return Math.ceil((100 * client.total - server.bytes.viewer) / perView).toLocaleString('en-US');
}

/** A log-scale bar chart of session bytes, per model and mode (the 10 Mbit/s runs, else the first profile). */
function plot(byModel) {
  const models = [...byModel.keys()];
  const anyRows = [...byModel.values()][0].rows;
  const profileNote = PROFILES[anyRows.some((r) => r.profile === '10mbit') ? '10mbit' : anyRows[0].profile].label;
  const colours = { png: '#4e79a7', webp: '#59a14f', jpg: '#f28e2b', rgba: '#bab0ac', client: '#e15759' };
  const W = 980;
  const H = 380;
  const left = 70;
  const bottom = 300;
  const top = 30;
  const lo = 2; // 100 B: the smallest encodings
  const hi = 9; // 1 GB
  const y = (b) => bottom - ((Math.log10(Math.max(b, 10 ** lo)) - lo) / (hi - lo)) * (bottom - top);
  const group = (W - left - 20) / models.length;
  const bar = (group - 20) / MODES.length;
  const parts = [
    `<svg xmlns="http://www.w3.org/2000/svg" width="${W}" height="${H}" viewBox="0 0 ${W} ${H}" font-family="sans-serif" font-size="12">`,
    `<rect width="${W}" height="${H}" fill="#fff"/>`,
    `<text x="${left}" y="18" font-size="14">Bytes on the wire for one pan-and-zoom session (log scale): server tiles by format vs client synthesis</text>`,
  ];
  for (let e = lo; e <= hi; e++) {
    const label = ['100 B', '1 kB', '10 kB', '100 kB', '1 MB', '10 MB', '100 MB', '1 GB'][e - lo];
    parts.push(`<line x1="${left}" x2="${W - 20}" y1="${y(10 ** e)}" y2="${y(10 ** e)}" stroke="#ddd"/>`);
    parts.push(`<text x="${left - 6}" y="${y(10 ** e) + 4}" text-anchor="end">${label}</text>`);
  }
  models.forEach((model, i) => {
    const { rows } = byModel.get(model);
    const profile = rows.some((r) => r.profile === '10mbit') ? '10mbit' : rows[0].profile;
    MODES.forEach((mode, j) => {
      const r = rows.find((x) => x.mode === mode && x.profile === profile);
      if (!r) return;
      const x = left + i * group + 10 + j * bar;
      parts.push(`<rect x="${x.toFixed(1)}" y="${y(r.total).toFixed(1)}" width="${(bar - 2).toFixed(1)}" height="${(bottom - y(r.total)).toFixed(1)}" fill="${colours[mode]}"><title>${model} ${mode}: ${MB(r.total)}</title></rect>`);
      // Inside each bar: what the texture itself cost (its tiles, or its encoding).
      const own = mode === 'client' ? r.bytes.encoding : r.bytes.tiles;
      parts.push(`<line x1="${x.toFixed(1)}" x2="${(x + bar - 2).toFixed(1)}" y1="${y(own).toFixed(1)}" y2="${y(own).toFixed(1)}" stroke="#000" stroke-width="2" stroke-dasharray="4 2"><title>${model} ${mode}: ${mode === 'client' ? 'encoding' : 'tiles'} ${MB(own)}</title></line>`);
    });
    parts.push(`<text x="${left + i * group + group / 2}" y="${bottom + 18}" text-anchor="middle">${model}</text>`);
  });
  MODES.forEach((mode, j) => {
    parts.push(`<rect x="${left + j * 130}" y="${H - 48}" width="12" height="12" fill="${colours[mode]}"/>`);
    parts.push(`<text x="${left + j * 130 + 16}" y="${H - 38}">${mode === 'client' ? 'client synthesis' : `${mode} tiles`}</text>`);
  });
  parts.push(`<line x1="${left}" x2="${left + 18}" y1="${H - 16}" y2="${H - 16}" stroke="#000" stroke-width="2" stroke-dasharray="4 2"/>`);
  parts.push(`<text x="${left + 24}" y="${H - 12}">in each bar: the texture's own bytes, its tiles or its encoding (the rest is the viewer's code, and the module in client mode)</text>`);
  parts.push(`<text x="${W - 20}" y="${bottom + 34}" text-anchor="end" fill="#555">${profileNote}</text>`);
  parts.push('</svg>');
  return parts.join('\n');
}

// ---------------------------------------------------------------------------------------------

async function main() {
  const dataDir = mkdtempSync(join(tmpdir(), 'vtex-bandwidth-data-'));
  try {
    // One start writes the demos into the data directory every session then reuses.
    const first = await startServer({ dataDir, embeddedViewer: true });
    const textures = (await (await fetch(`${first.url}/api/v1/textures`)).json()).textures;
    const module = moduleFile(textures[0].model);
    const served = Buffer.from(await (await fetch(`${first.url}/${module}`)).arrayBuffer());
    await first.stop();
    if (!served.equals(readFileSync(join(ROOT, 'client-web', 'dist', module)))) {
      throw new Error('target/release/vtex embeds another viewer build than client-web/dist: build it again (cargo build --release -p vtex-server)');
    }
    const commit = spawnSync('git', ['rev-parse', '--short', 'HEAD'], { cwd: ROOT, encoding: 'utf8' }).stdout.trim();
    const chromium = spawnSync(CHROMIUM, ['--version'], { encoding: 'utf8' }).stdout.trim();
    const byModel = new Map();
    for (const model of args.models.split(',')) {
      const info =
        textures.find((t) => t.name === FLAGSHIPS[model]) ||
        textures.filter((t) => t.model === model).sort((a, b) => b.width * b.height - a.width * a.height)[0];
      if (!info) throw new Error(`no texture of model ${model}`);
      const load0 = loadavg()[0];
      const explicit = await explicitSize(dataDir, info);
      const rows = [];
      for (const profile of profiles) {
        for (const mode of modesFor(profile)) {
          const r = await session(dataDir, info, mode, profile);
          console.error(`${model} ${mode} ${profile}: ${MB(r.total)}, first view ${sec(r.firstViewMs)}, end ${sec(r.endMs)}${r.complete ? '' : ' (cut)'}, cpu ${r.cpu.client.toFixed(1)} s`);
          rows.push(r);
        }
      }
      byModel.set(model, { info, explicit, rows, load: [load0, loadavg()[0]] });
    }
    const when = new Date().toISOString().slice(0, 16).replace('T', ' ');
    const run = { when, commit, chromium, args, argv: process.argv.slice(2), size: SIZE, cap: args.cap, results: Object.fromEntries(byModel) };
    mkdirSync(dirname(args.json), { recursive: true });
    writeFileSync(args.json, JSON.stringify(run, null, 1));
    write(run);
  } finally {
    rmSync(dataDir, { recursive: true, force: true });
  }
}

/** Writes docs/bandwidth.md and docs/bandwidth.svg from a run's figures. */
function write(run) {
  const { when, commit, chromium, results } = run;
  // Runs written before the file recorded these: their defaults.
  const { argv = ['--json', run.args.json.replace(`${ROOT}/`, '')], size = SIZE, cap = args.cap } = run;
  const byModel = new Map(Object.entries(results));
  {
    const loads = [...byModel].map(([m, v]) => `${m} ${v.load.map((l) => l.toFixed(1)).join('→')}`).join(', ');
    const md = [
      '# The bandwidth experiment: server tiles against client synthesis',
      '',
      `Written by \`node bench/bandwidth.mjs ${argv.join(' ')}\` (${when} UTC, commit ${commit}, ${chromium}, ${cpus().length} cores shared with other work; load average at the start → end of each model: ${loads}). How to read it and what it shows: \`docs/client-synthesis.md\`, "The bandwidth experiment".`,
      '',
      `Session: the whole texture, then ${SESSION.length} views (zooms to level 0, pans there, jumps, zooms out and in elsewhere), each applied at once after the previous one was complete, in a ${size.width} × ${size.height} viewport. Fresh server and browser profile per session; sessions cut at ${cap} s.`,
      '',
      paperSection(byModel.get('chaos-mosaic')?.info),
      '',
      '## Summary',
      '',
      summary(byModel),
      '',
      '![bytes on the wire per session](bandwidth.svg)',
      '',
      '## Every session',
      '',
      [...byModel].map(([model, v]) => modelSection(model, v.info, v.explicit, v.rows)).join('\n\n'),
      '',
    ].join('\n');
    mkdirSync(args.out, { recursive: true });
    writeFileSync(join(args.out, 'bandwidth.md'), md);
    writeFileSync(join(args.out, 'bandwidth.svg'), plot(byModel));
    console.error(`wrote ${join(args.out, 'bandwidth.md')} and bandwidth.svg`);
  }
}

if (args.render) write(JSON.parse(readFileSync(args.render, 'utf8')));
else await main();
