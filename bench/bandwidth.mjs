// The bandwidth experiment of the Chaos Mosaic paper (§3.3: ship the encoding, let the client
// synthesize), in one series: a scripted pan-and-zoom session in headless Chromium over the
// flagship 100k demo of every model, once per mode — server tiles as png, webp, jpg and rgba,
// and client synthesis (`?synth=client`: the encoding and the model's WebAssembly module, no tile
// requests) — under loopback and Chromium's network emulation (10 Mbit/s with 40 ms RTT, and
// DevTools' "Slow 4G"), on a first visit and, for client mode, a returning one (code and module
// in the HTTP cache); a long session of 100 views, jpg against client mode, for a returning
// visitor; and the 3D world's walk (world.html) with pages synthesized in the browser against
// JPEG and BC7 KTX2 pages from the server, under the same profiles and visits. Writes
// docs/bandwidth.md (tables), docs/bandwidth.svg (plot) and the raw figures as JSON.
//
//   node bench/bandwidth.mjs [--models chaos-mosaic,lcm]
//        [--modes png,webp,jpg,rgba,client] [--profiles loopback,10mbit,slow4g]
//        [--slow-modes jpg,client] [--long 100] [--world-modes client,jpg,ktx2]
//        [--world-steps 240] [--cap 150] [--samples 6] [--out docs]
//        [--json bench/results/bandwidth.json]
//   node bench/bandwidth.mjs --render bench/results/bandwidth.json   (tables and plot again)
//
// (It takes the lock itself when started without it.) Needs the viewer built with the modules
// (scripts/build-wasm, then client-web's `npm run build`), then target/release/vtex built (it
// embeds the viewer, whose files it serves as deployed: brotli copies from the viewer's build),
// and Debian's Chromium. The sessions themselves: bench/bandwidth/sessions.mjs; the tables and
// the plot: bench/bandwidth/report.mjs.
import { spawnSync } from 'node:child_process';
import { readFileSync, writeFileSync, mkdirSync, mkdtempSync, rmSync } from 'node:fs';
import { cpus, loadavg, tmpdir } from 'node:os';
import { dirname, join } from 'node:path';
import { parseArgs } from 'node:util';
import { ROOT, CHROMIUM, startServer } from '../tests/browser/lib.mjs';
import { moduleFile } from '../client-web/src/shared/vtex-synth.js';
import { report } from './bandwidth/report.mjs';
import { PROFILES, viewerSession, worldWalk } from './bandwidth/sessions.mjs';

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
    // Views of the long session (jpg against client mode, returning visitor; 0: none).
    long: { type: 'string', default: '100' },
    // The 3D world's page sources (none: no world) and the frames of its walk.
    'world-modes': { type: 'string', default: 'client,jpg,ktx2' },
    'world-steps': { type: 'string', default: '240' },
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

/**
 * The long session: the whole texture, then `n - 1` views of a seeded walk over a texture
 * `width` level-0 pixels wide, seen in a viewport `viewport` pixels wide: half pans by up to a
 * viewport, three in ten zooms by one to three levels, two in ten jumps to a random place and zoom.
 * Zooms are powers of two from 1/64 to 2.
 */
function longSession(n, width, viewport) {
  let seed = 0x2545f491;
  const random = () => {
    seed = (Math.imul(seed, 1103515245) + 12345) >>> 0;
    return seed / 2 ** 32;
  };
  const clamp = (v) => Math.min(0.98, Math.max(0.02, v));
  const views = [SESSION[0]];
  let [level, x, y] = [0, 0.5, 0.5]; // zoom 2^-level
  while (views.length < n) {
    const r = random();
    if (r < 0.5) {
      const reach = viewport / 2 ** -level / width;
      x = clamp(x + (random() - 0.5) * 2 * reach);
      y = clamp(y + (random() - 0.5) * 2 * reach);
    } else if (r < 0.8) {
      const by = 1 + Math.floor(random() * 3);
      level = Math.min(6, Math.max(-1, level + (random() < 0.5 ? -by : by)));
    } else {
      [level, x, y] = [Math.floor(random() * 8) - 1, clamp(random()), clamp(random())];
    }
    views.push([2 ** -level, x, y]);
  }
  return views;
}

const sum = (xs) => xs.reduce((a, b) => a + b, 0);

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

const MB = (n) => `${(n / 1e6).toFixed(2)} MB`;
const sec = (ms) => (ms === undefined ? '–' : `${(ms / 1000).toFixed(2)} s`);
const log = (what, r) => console.error(`${what} ${r.mode} ${r.profile}${r.returning ? ' (returning)' : ''}: ${MB(r.total)}, first view ${sec(r.firstViewMs)}, end ${sec(r.endMs)}${r.complete ? '' : ' (cut)'}, cpu ${r.cpu.client.toFixed(1)} s`);

/** Every session of one model's flagship: each profile and mode on a first visit, client mode returning, and the long sessions. */
async function modelSessions(dataDir, info) {
  const base = { dataDir, info, size: SIZE, capMs: CAP_MS };
  const rows = [];
  for (const profile of profiles) {
    for (const mode of modesFor(profile)) {
      const first = await viewerSession({ ...base, mode, profile, views: SESSION });
      log(info.model, first);
      rows.push(first);
      if (mode !== 'client') continue;
      const returning = await viewerSession({ ...base, mode, profile, views: SESSION, returning: first });
      log(info.model, returning);
      rows.push(returning);
    }
  }
  const long = [];
  const views = longSession(Number(args.long), info.width, SIZE.width);
  for (const mode of Number(args.long) > 0 ? ['jpg', 'client'] : []) {
    const first = rows.find((r) => r.mode === mode && !r.returning);
    const r = await viewerSession({ ...base, mode, profile: first.profile, views, capMs: 10 * CAP_MS, returning: first });
    log(`${info.model} long`, r);
    long.push(r);
  }
  return { rows, long };
}

/** The world's walk from each page source under each profile, first visit, and client mode returning. */
async function worldSessions(dataDir) {
  const rows = [];
  const base = { dataDir, size: SIZE, steps: Number(args['world-steps']), capMs: CAP_MS };
  for (const profile of profiles) {
    for (const mode of args['world-modes'].split(',').filter(Boolean)) {
      const first = await worldWalk({ ...base, mode, profile });
      log('world', first);
      rows.push(first);
      if (mode !== 'client') continue;
      const returning = await worldWalk({ ...base, mode, profile, returning: first });
      log('world', returning);
      rows.push(returning);
    }
  }
  return { rows, steps: base.steps };
}

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
    const run = {
      when: new Date().toISOString().slice(0, 16).replace('T', ' '),
      commit: spawnSync('git', ['rev-parse', '--short', 'HEAD'], { cwd: ROOT, encoding: 'utf8' }).stdout.trim(),
      chromium: spawnSync(CHROMIUM, ['--version'], { encoding: 'utf8' }).stdout.trim(),
      cores: cpus().length,
      argv: process.argv.slice(2),
      size: SIZE,
      cap: args.cap,
      sessionViews: SESSION.length,
      longViews: Number(args.long),
      models: {},
      world: null,
    };
    for (const model of args.models.split(',').filter(Boolean)) {
      const info =
        textures.find((t) => t.name === FLAGSHIPS[model]) ||
        textures.filter((t) => t.model === model).sort((a, b) => b.width * b.height - a.width * a.height)[0];
      if (!info) throw new Error(`no texture of model ${model}`);
      const load0 = loadavg()[0];
      const explicit = await explicitSize(dataDir, info);
      run.models[model] = { info, explicit, ...(await modelSessions(dataDir, info)), load: [load0, loadavg()[0]] };
    }
    if (args['world-modes']) {
      const load0 = loadavg()[0];
      run.world = { ...(await worldSessions(dataDir)), load: [load0, loadavg()[0]] };
    }
    mkdirSync(dirname(args.json), { recursive: true });
    writeFileSync(args.json, JSON.stringify(run, null, 1));
    write(run);
  } finally {
    rmSync(dataDir, { recursive: true, force: true });
  }
}

/** Writes docs/bandwidth.md and docs/bandwidth.svg from a run's figures. */
function write(run) {
  const { md, svg } = report(run);
  mkdirSync(args.out, { recursive: true });
  writeFileSync(join(args.out, 'bandwidth.md'), md);
  writeFileSync(join(args.out, 'bandwidth.svg'), svg);
  console.error(`wrote ${join(args.out, 'bandwidth.md')} and bandwidth.svg`);
}

if (args.render) write(JSON.parse(readFileSync(args.render, 'utf8')));
else await main();
