// A measured pan-and-zoom session in headless Chromium against a real `vtex serve` (loopback).
//
//   node bench/viewer/bench.mjs [--steps 60] [--pan-seconds 5] [--shots DIR] [--json FILE]
//        [--trace] [--texture NAME] [--server-args="--tile-size 512"] [--osd JSON] [--playwright]
//        [--format rgba|png|webp|jpg] [--detail map|sharp] [--profile FILE.cpuprofile] [--chrome-trace FILE.json]
//        [--phase random|after] [--shift SEED] [--width 1280] [--height 800] [--passes all|cold]
//
// The texture is the 100k × 100k chaos mosaic (the flagship demo, as bench/server/run.sh picks
// it) unless --texture names another. Chromium is driven over a bare DevTools pipe (cdp.mjs):
// Playwright's network instrumentation would add Chromium CPU to every tile request.
//
// 1. View changes: a fixed, seeded sequence of jumps, pans and zooms over the texture. For
//    each, the time from the change (applied at once, no animation) to the first OpenSeadragon
//    frame that has drawn every tile the new view needs, to two points of that frame: its draw
//    calls issued (the end of its animation-frame callback), and its work on the main thread
//    done, the canvas raster included (a message posted from the callback runs right after;
//    the figure the targets are read against: the raster happens at the frame's commit, after
//    the callback). A view is done in an
//    animation frame, so where in the frame clock the change lands counts: by default each is
//    applied at a seeded random point of a frame, as a click, a key or a link arrives
//    (--phase random); --phase after applies it as soon as the previous view was drawn, which
//    locks the whole pass to one phase that depends on how long the viewer's frames take. Four
//    passes:
//      cold         fresh server (empty tile cache) and fresh browser profile;
//      warm-browser same browser after a reload (tiles from its HTTP cache, OSD's memory empty);
//      warm-server  fresh browser profile; every tile comes from the server's cache (2 GiB, so
//                   the whole session fits);
//      warm-viewer  same page: after each view, back to the one before (tiles in OSD's memory).
//    --trace breaks every view change into stages (trace.mjs); --shots also takes screenshots
//    two frames after a zoom, a pan and a jump, before the new tiles arrive.
// 2. A continuous pan at level 0 (a steady drag across fresh texture), recording every
//    animation-frame interval, cold and then warm (the same path again).
import { parseArgs } from 'node:util';
import { mkdirSync, writeFileSync } from 'node:fs';
import { debugUrl, launchBrowser, openViewer, startServer, viewerIdle } from '../../tests/browser/lib.mjs';
import { launchBare } from './cdp.mjs';
import { collectTrace, formatBreakdown, installTracer, viewBreakdown } from './trace.mjs';

const { values: args } = parseArgs({
  options: {
    steps: { type: 'string', default: '60' },
    'pan-seconds': { type: 'string', default: '5' },
    'pan-speed': { type: 'string', default: '8' },
    shots: { type: 'string' },
    json: { type: 'string' },
    width: { type: 'string', default: '1280' },
    height: { type: 'string', default: '800' },
    // Per-stage timing of every view change (bench/viewer/trace.mjs); adds a little overhead.
    trace: { type: 'boolean', default: false },
    // DevTools CPU profile of the page's main thread during the warm-server pass, written to
    // FILE (.cpuprofile, opens in DevTools) and summarised per view (bare DevTools driver only).
    profile: { type: 'string' },
    // Chromium trace of every process (renderer, network service, viz) during the warm-server
    // pass, written to FILE (JSON; opens in Perfetto or chrome://tracing; bare driver only).
    'chrome-trace': { type: 'string' },
    // Extra OpenSeadragon options as JSON, merged over the viewer's (A/B experiments only).
    osd: { type: 'string' },
    // Server flags, e.g. --server-args "--max-syntheses 4".
    'server-args': { type: 'string', default: '' },
    // Drive Chromium with Playwright (its network instrumentation adds CPU to every request)
    // instead of the bare DevTools pipe (bench/viewer/cdp.mjs).
    playwright: { type: 'boolean', default: false },
    // Texture to measure (name, id or model); default: the 100k × 100k chaos mosaic.
    texture: { type: 'string' },
    // Tile format the viewer asks for (its `format` URL parameter); default: the viewer's (rgba on loopback).
    format: { type: 'string' },
    // Level choice (the viewer's `detail` URL parameter, client-web/src/viewer/pyramid.js DETAIL);
    // default: the viewer's (map).
    detail: { type: 'string' },
    // When each view change is applied: at a seeded random point of an animation frame
    // (random), or right after the previous view was drawn (after).
    phase: { type: 'string', default: 'random' },
    // Another user over the same places: every view of the session moved by a seeded random
    // fraction (up to one) of a view each way (bench/replicas/viewer-hit-ratio.mjs).
    shift: { type: 'string' },
    // `cold`: the cold pass alone (no pans, no warm passes), as a user arriving at a server
    // (or a cache in front of it) that others have used.
    passes: { type: 'string', default: 'all' },
  },
});
const STEPS = Number(args.steps);
const PAN_SECONDS = Number(args['pan-seconds']);
const PAN_SPEED = Number(args['pan-speed']); // screen pixels per frame
const SIZE = { width: Number(args.width), height: Number(args.height) };
if (!['random', 'after'].includes(args.phase)) throw new Error(`--phase ${args.phase}: expected random or after`);
/** A 60 Hz display's frame interval: the range of the random phase. */
const FRAME_MS = 1000 / 60;

/** Small seeded PRNG (mulberry32) so every run replays the same session. */
function rng(seed) {
  let a = seed >>> 0;
  return () => {
    a = (a + 0x6d2b79f5) >>> 0;
    let t = a;
    t = Math.imul(t ^ (t >>> 15), t | 1);
    t ^= t + Math.imul(t ^ (t >>> 7), t | 61);
    return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
  };
}

/** A fixed piece of integer work for `cpuReference`: `n` mulberry32 steps, summed in int32. */
function referenceWork(seed, n) {
  let a = seed | 0;
  let sum = 0;
  for (let i = 0; i < n; i++) {
    a = (a + 0x6d2b79f5) | 0;
    let t = Math.imul(a ^ (a >>> 15), a | 1);
    t ^= t + Math.imul(t ^ (t >>> 7), t | 61);
    sum = (sum + (t ^ (t >>> 14))) | 0;
  }
  return sum;
}

/**
 * ms this machine takes for five million steps of `referenceWork` (median of 5 rounds), taken
 * before and after each pass: a machine's speed can change within minutes (frequency
 * scaling, a shared host), so passes are only comparable beside it. The first call warms
 * V8 up first (type feedback, then one optimised round), so every figure is of the same code.
 */
function cpuReference() {
  const round = (seed) => {
    const t = performance.now();
    const sum = referenceWork(seed, 5_000_000);
    return [performance.now() - t, sum];
  };
  if (!cpuReference.warm) {
    for (let i = 0; i < 100; i++) referenceWork(i, 1000);
    round(0);
    cpuReference.warm = true;
  }
  const rounds = [1, 2, 3, 4, 5].map(round);
  // The sums are used, so V8 cannot drop the work as dead code.
  if (rounds.every(([, sum]) => sum === 0)) throw new Error('the reference work gave nothing');
  return rounds.map(([ms]) => ms).sort((a, b) => a - b)[2];
}

/** Screen pixels the session's pans are measured in, whatever the window: one path for all. */
const PATH_WIDTH = 1280;

/** The session: views (zoom in screen px per level-0 px, centre in level-0 px). */
function session(info, steps) {
  const r = rng(1);
  const views = [];
  let v = { zoom: 0.05, x: info.width / 2, y: info.height / 2 };
  for (let i = 0; i < steps; i++) {
    const kind = i % 3;
    if (kind === 0) {
      // jump somewhere new at a zoom between 1/128 and 2
      v = { zoom: 2 ** (-7 + 8 * r()), x: info.width * (0.05 + 0.9 * r()), y: info.height * (0.05 + 0.9 * r()) };
    } else if (kind === 1) {
      // pan by half to one screen
      const a = 2 * Math.PI * r();
      const d = (0.5 + 0.5 * r()) * PATH_WIDTH;
      v = { ...v, x: v.x + (Math.cos(a) * d) / v.zoom, y: v.y + (Math.sin(a) * d) / v.zoom };
    } else {
      // zoom in or out by 2 about the centre
      v = { ...v, zoom: r() < 0.5 ? v.zoom * 2 : v.zoom / 2 };
    }
    v.zoom = Math.min(4, Math.max(1 / 256, v.zoom));
    v.x = Math.min(info.width - 1, Math.max(0, v.x));
    v.y = Math.min(info.height - 1, Math.max(0, v.y));
    views.push({ ...v });
  }
  return args.shift === undefined ? views : views.map(shifted(info, rng(Number(args.shift))));
}

/** `view` moved by a random fraction in (−1, 1) of the view's width and height each way. */
function shifted(info, r) {
  return (v) => {
    const dx = ((2 * r() - 1) * SIZE.width) / v.zoom;
    const dy = ((2 * r() - 1) * SIZE.height) / v.zoom;
    return { ...v, x: Math.min(info.width - 1, Math.max(0, v.x + dx)), y: Math.min(info.height - 1, Math.max(0, v.y + dy)) };
  };
}

/** What --chrome-trace records: tasks, frames, canvas and compositing, network and IPC. */
const CHROME_TRACE_CATEGORIES = [
  'toplevel',
  'devtools.timeline',
  'disabled-by-default-devtools.timeline',
  'blink',
  'cc',
  'viz',
  'gpu',
  'netlog',
  'mojom',
  'loading',
  'v8',
  // V8's sampling profiler on every thread (the Worker's JavaScript by function).
  'disabled-by-default-v8.cpu_profiler',
];

function summary(ms) {
  const s = [...ms].sort((a, b) => a - b);
  const q = (p) => s[Math.min(s.length - 1, Math.max(0, Math.ceil(p * s.length) - 1))];
  return { n: s.length, p50: q(0.5), p95: q(0.95), max: s[s.length - 1], mean: s.reduce((a, b) => a + b, 0) / s.length };
}

/**
 * Applies `view` at once and resolves once every tile it needs is drawn. With a `delay`
 * (ms), the change is applied that long after the start of the next animation frame;
 * without, at once.
 */
function showView(page, view, delay = null) {
  return page.evaluate(
    ({ view, delay }) =>
      // Kept on `window` until it settles: DevTools reports an awaited promise it sees
      // collected ("Promise was collected", 3 runs in ~60), and only the handlers below held it.
      (window.__vtexShowView = (
        delay === null ? Promise.resolve() : new Promise((r) => requestAnimationFrame(() => setTimeout(r, delay)))
      ).then(() => new Promise((resolve, reject) => {
        const { viewer, state, setView, stats } = window.vtexViewer;
        const requested0 = stats.requested;
        const batches0 = stats.batches;
        console.timeStamp('vtex view change'); // marks the change in a --chrome-trace
        const t0 = performance.now();
        // What is still loading, for the error: the tile source's started jobs and OSD's tiles.
        const stuck = () => {
          const jobs = [...(state.item.source.vtexInFlight || [])].map((j) => ({
            src: j.src.replace(/^.*\/tiles\//, ''),
            done: j.userData.done,
            settled: j.userData.settled,
            batched: Boolean(j.userData.batchUrl),
            age: Math.round(performance.now() - j.userData.t0),
          }));
          const loading = [];
          for (const level of Object.values(state.item.tilesMatrix || {}))
            for (const col of Object.values(level)) for (const t of Object.values(col)) if (t.loading) loading.push(t.getUrl().replace(/^.*\/tiles\//, ''));
          return JSON.stringify({ jobs, loading, inProgress: viewer.imageLoader.jobsInProgress, fullyLoaded: state.item.getFullyLoaded() });
        };
        const timer = setTimeout(() => reject(new Error(`view not drawn in 30 s: ${JSON.stringify(view)}; ${stuck()}`)), 30_000);
        // update-viewport follows every draw; the first one after which the image is fully
        // loaded and needs no further draw is the frame that completed the view. Its draw calls
        // are then issued (t1); the canvas rasters them later in the same task, when the frame
        // is committed, after style, layout and paint. A message posted now runs right after
        // that task: the end of the frame's work on the main thread (`rasterMs`, the usual
        // stand-in for "next paint"; the compositor's own work to put it on screen follows).
        // The first complete coarse frame: every tile of the finest level under the view drawn
        // at that level or at most 3 coarser (osd-adapter.js PREVIEW_STEPS: the preview
        // level). A view the previous one left covered at an intermediate level has it at once:
        // OpenSeadragon then asks for no preview tile.
        const info = state.info;
        const top = info.levels - 1;
        const finest = Math.min(top, Math.max(0, Math.floor(Math.log2((view.zoom * 2 ** top) / viewer.minPixelRatio))));
        const coarse = Math.max(0, finest - 3);
        const coarseDrawn = () => {
          const b = state.item.viewportToImageRectangle(viewer.viewport.getBounds(true));
          const side = info.tile_size * 2 ** (top - finest);
          const span = (a, len, size) => [Math.max(0, Math.floor(a / side)), Math.min(Math.ceil(size / side), Math.ceil((a + len) / side)) - 1];
          const [x0, x1] = span(b.x, b.width, info.width);
          const [y0, y1] = span(b.y, b.height, info.height);
          const loaded = (level, x, y) => {
            const col = (state.item.tilesMatrix[level] || {})[x];
            return Boolean(col && col[y] && col[y].loaded);
          };
          const covered = (x, y) => {
            for (let l = finest; l >= coarse; l--) if (loaded(l, x >> (finest - l), y >> (finest - l))) return true;
            return false;
          };
          for (let x = x0; x <= x1; x++) for (let y = y0; y <= y1; y++) if (!covered(x, y)) return false;
          return true;
        };
        let coarseMs = null;
        const check = () => {
          const fully = state.item.getFullyLoaded();
          if (coarseMs === null && (fully || coarseDrawn())) coarseMs = performance.now() - t0;
          if (fully && !viewer.world.needsDraw()) {
            viewer.removeHandler('update-viewport', check);
            clearTimeout(timer);
            const t1 = performance.now();
            const after = new MessageChannel();
            after.port1.onmessage = () =>
              resolve({ ms: t1 - t0, rasterMs: performance.now() - t0, coarseMs, t0, t1, tiles: stats.requested - requested0, requests: stats.batches - batches0 });
            after.port2.postMessage(null);
          }
        };
        viewer.addHandler('update-viewport', check);
        setView(view, true);
        viewer.forceRedraw();
      })).finally(() => delete window.__vtexShowView)),
    { view, delay },
  );
}

/**
 * Applies each view at once and measures until every tile it needs is drawn. With `back`,
 * each measured view is the previous one revisited: views[i] is shown first (not measured),
 * then views[i-1] is measured — its tiles are still in OpenSeadragon's memory.
 */
async function measureViews(page, views, shots, tag, { back = false } = {}) {
  const referenceBefore = cpuReference();
  // The same phases in every pass and run (--phase random).
  const phase = rng(2);
  const delay = () => (args.phase === 'random' ? phase() * FRAME_MS : null);
  const times = [];
  const rasterTimes = [];
  const coarseTimes = [];
  const tiles = [];
  const requests = [];
  const breakdowns = [];
  // The tiles the canvas drawer draws, with the canvas pixels they cover.
  const canvasCounts = () =>
    page.evaluate(() => {
      const drawer = window.vtexViewer.viewer.drawer;
      if (!drawer.vtexDrawn && typeof drawer._drawTile === 'function') {
        drawer.vtexDrawn = { tiles: 0, pixels: 0 };
        const drawTile = drawer._drawTile.bind(drawer);
        drawer._drawTile = (tile, ...rest) => {
          const r = OpenSeadragon.pixelDensityRatio;
          const w = Math.min(drawer.canvas.width, (tile.position.x + tile.size.x) * r) - Math.max(0, tile.position.x * r);
          const h = Math.min(drawer.canvas.height, (tile.position.y + tile.size.y) * r) - Math.max(0, tile.position.y * r);
          drawer.vtexDrawn.tiles++;
          drawer.vtexDrawn.pixels += Math.max(0, w) * Math.max(0, h);
          return drawTile(tile, ...rest);
        };
      }
      const d = drawer.vtexDrawn || {};
      return { drawnTiles: d.tiles, drawnPixels: d.pixels };
    });
  const canvas0 = await canvasCounts();
  if (args.trace) await page.evaluate(installTracer);
  for (let i = back ? 1 : 0; i < views.length; i++) {
    if (back) await showView(page, views[i]);
    if (args.trace) await page.evaluate(collectTrace, { t0: 0, t1: -1 }); // forget the unmeasured view
    const r = await showView(page, back ? views[i - 1] : views[i], delay());
    times.push(r.ms);
    rasterTimes.push(r.rasterMs);
    coarseTimes.push(r.coarseMs);
    tiles.push(r.tiles);
    requests.push(r.requests);
    if (args.trace) {
      const trace = await page.evaluate(collectTrace, { t0: r.t0, t1: r.t1 });
      breakdowns.push(viewBreakdown({ ...trace, t0: r.t0, t1: r.t1 }));
    }
    if (shots && i % 15 === 0) await page.screenshot(`${shots}/${tag}-${i}.png`);
  }
  if (!times.length) return null;
  const canvas1 = await canvasCounts();
  const canvas = {};
  for (const k of ['drawnTiles', 'drawnPixels']) canvas[k] = canvas1[k] === undefined ? null : (canvas1[k] - canvas0[k]) / times.length;
  const perView = (v) => v.reduce((a, b) => a + (b || 0), 0) / v.length;
  const cpuReferenceMs = [referenceBefore, cpuReference()];
  return { ...summary(times), raster: summary(rasterTimes), coarse: summary(coarseTimes), tilesPerView: perView(tiles), requestsPerView: perView(requests), canvasPerView: canvas, cpuReferenceMs, times, rasterTimes, coarseTimes, tiles, breakdowns };
}

/**
 * Screenshots two frames after a view change, before the new tiles arrive: a zoom in, a pan
 * by one screen and a jump into texture never seen. Coarser levels already loaded must show
 * where the new tiles are still missing (no black holes).
 */
async function midLoadShots(page, dir, info) {
  const v = await page.evaluate(() => window.vtexViewer.getView());
  const steps = [
    ['zoom-in', { zoom: v.zoom * 2, x: v.x + 3000, y: v.y + 3000 }],
    ['pan', { zoom: v.zoom * 2, x: v.x + 3000 + 960 / (v.zoom * 2), y: v.y + 3000 }],
    ['jump', { zoom: 0.3, x: info.width * 0.31, y: info.height * 0.77 }],
  ];
  for (const [name, view] of steps) {
    await page.evaluate(
      (view) =>
        new Promise((resolve) => {
          window.vtexViewer.setView(view, true);
          requestAnimationFrame(() => requestAnimationFrame(resolve));
        }),
      view,
    );
    await page.screenshot(`${dir}/mid-load-${name}.png`);
    await idle(page);
  }
}

/** A steady pan of PAN_SPEED screen px per frame for PAN_SECONDS, recording frame intervals. */
async function measurePan(page, start) {
  return page.evaluate(
    ({ start, seconds, speed }) =>
      new Promise((resolve) => {
        const { viewer, setView, stats } = window.vtexViewer;
        setView(start, true);
        const requested0 = stats.requested;
        const frames = [];
        let last = 0;
        const t0 = performance.now();
        const step = (now) => {
          if (last) frames.push(now - last);
          last = now;
          const d = viewer.viewport.deltaPointsFromPixels(new OpenSeadragon.Point(speed, speed * 0.3), true);
          viewer.viewport.panBy(d, true);
          if (now - t0 < seconds * 1000) requestAnimationFrame(step);
          else resolve({ frames, tiles: stats.requested - requested0 });
        };
        requestAnimationFrame(step);
      }),
    { start, seconds: PAN_SECONDS, speed: PAN_SPEED },
  );
}

function panSummary({ frames, tiles }) {
  const s = summary(frames);
  return { ...s, over50: frames.filter((f) => f > 50).length, over33: frames.filter((f) => f > 33.4).length, tiles };
}

/** Server-side counters from /metrics: syntheses, their total seconds, misses by level. */
async function serverCounters(url) {
  const text = await (await fetch(`${url}/metrics`)).text();
  const value = (re) => {
    const m = text.match(re);
    return m ? Number(m[1]) : 0;
  };
  const misses = {};
  for (const m of text.matchAll(/^vtex_tile_cache_misses_total\{level="(\d+)"\} (\S+)$/gm)) misses[m[1]] = Number(m[2]);
  // The synthesis histogram has a series per model: summed over models.
  const sum = (re) => [...text.matchAll(re)].reduce((total, m) => total + Number(m[1]), 0);
  const byBound = new Map();
  for (const m of text.matchAll(/^vtex_synthesis_seconds_bucket\{[^}]*le="([^"]+)"[^}]*\} (\S+)$/gm)) {
    byBound.set(m[1], (byBound.get(m[1]) || 0) + Number(m[2]));
  }
  const buckets = [...byBound];
  return {
    syntheses: value(/^vtex_syntheses_total (\S+)$/m),
    synthSeconds: sum(/^vtex_synthesis_seconds_sum\{[^}]*\} (\S+)$/gm),
    synthCount: sum(/^vtex_synthesis_seconds_count\{[^}]*\} (\S+)$/gm),
    buckets,
    misses,
  };
}

/** What the server did between two counter snapshots. */
function serverDelta(a, b) {
  const misses = {};
  for (const [level, n] of Object.entries(b.misses)) if (n - (a.misses[level] || 0) > 0) misses[level] = n - (a.misses[level] || 0);
  const count = b.synthCount - a.synthCount;
  return {
    syntheses: count,
    synthMeanMs: count ? (1000 * (b.synthSeconds - a.synthSeconds)) / count : NaN,
    synthBuckets: b.buckets.map(([le, n], i) => [le, n - (a.buckets[i] ? a.buckets[i][1] : 0)]),
    missesByLevel: misses,
  };
}

/**
 * The texture to measure: by default the 100k × 100k chaos mosaic, the flagship demo (as
 * bench/server/run.sh picks it); `--texture` names another (name, id or model).
 */
function pickTexture(textures, key) {
  const big = (t) => t.width >= 100_000 && t.height >= 100_000;
  const found = key
    ? textures.find((t) => t.id === key || t.name === key) || textures.find((t) => t.model === key && big(t))
    : textures.find((t) => t.model === 'chaos-mosaic' && big(t));
  if (!found) throw new Error(`no texture ${key ? `"${key}"` : '100k × 100k chaos-mosaic'} on the server: ${textures.map((t) => t.name).join(', ')}`);
  return found;
}

/** Source of an init script merging `--osd` options over the viewer's when it builds its viewer. */
function osdInitScript(overrides) {
  return `(${((o) => {
    // After openseadragon.min.js ran (its script element's load event) and before main.js.
    document.addEventListener(
      'load',
      (e) => {
        if (!(e.target instanceof HTMLScriptElement) || !e.target.src.includes('openseadragon')) return;
        window.OpenSeadragon = new Proxy(window.OpenSeadragon, {
          apply: (target, self, [options]) => target({ ...options, ...o }),
        });
      },
      true,
    );
  }).toString()})(${JSON.stringify(overrides)})`;
}

/**
 * A fresh browser profile with the viewer open at `url`, as { evaluate, waitFor, reload,
 * screenshot, close }: over the bare DevTools pipe, or with `--playwright` through Playwright.
 */
async function openPage(url) {
  const initScript = args.osd ? osdInitScript(JSON.parse(args.osd)) : undefined;
  let page;
  if (args.playwright) {
    const b = await launchBrowser(SIZE);
    if (initScript) await b.context.addInitScript({ content: initScript });
    const p = (await openViewer(b.context, url)).page;
    page = {
      evaluate: (fn, arg) => p.evaluate(fn, arg),
      waitFor: (fn, arg, { timeout = 60_000 } = {}) => p.waitForFunction(fn, arg, { timeout, polling: 50 }),
      reload: () => p.reload(),
      screenshot: (path) => p.screenshot({ path }),
      close: () => b.close(),
    };
  } else {
    page = await launchBare(debugUrl(url), { ...SIZE, initScript });
  }
  await page.waitFor(() => window.vtexViewer && window.vtexViewer.state.item);
  return page;
}

/**
 * Main-thread time of a DevTools CPU profile per view: idle, garbage collection, "(program)"
 * (the browser's own work outside JS: painting, rastering, IPC) and JS, with the functions that
 * took the most self time.
 */
function profileSummary(profile, views) {
  const self = new Map();
  const byId = new Map(profile.nodes.map((n) => [n.id, n]));
  for (let i = 0; i < profile.samples.length; i++) {
    const n = byId.get(profile.samples[i]);
    const f = n.callFrame;
    const key = f.url ? `${f.functionName || '(anonymous)'} ${f.url.replace(/^.*\//, '')}:${f.lineNumber + 1}` : f.functionName;
    self.set(key, (self.get(key) || 0) + profile.timeDeltas[i] / 1000);
  }
  const total = (profile.endTime - profile.startTime) / 1000;
  const pick = (k) => self.get(k) || 0;
  const special = ['(idle)', '(program)', '(garbage collector)', '(root)'];
  const js = [...self].filter(([k]) => !special.includes(k));
  const per = (ms) => ms / views;
  return {
    msPerView: per(total),
    idle: per(pick('(idle)')),
    program: per(pick('(program)')),
    gc: per(pick('(garbage collector)')),
    js: per(js.reduce((a, [, v]) => a + v, 0)),
    top: js
      .sort((a, b) => b[1] - a[1])
      .slice(0, 12)
      .map(([k, v]) => [k, +per(v).toFixed(2)]),
  };
}

/** Resolves when every tile the current view needs is loaded and drawn (tests/browser/lib.mjs waitForIdle). */
async function idle(page) {
  await page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
  await page.waitFor(viewerIdle);
}

// The session's raw tiles must fit the server's cache for "warm server" to be warm: 2 GiB
// holds them.
if (args.shots) mkdirSync(args.shots, { recursive: true });
const serverArgs = ['--cache-mb', '2048', ...args['server-args'].split(/\s+/).filter(Boolean)];
const server = await startServer({ extraArgs: serverArgs });
const results = { when: new Date().toISOString(), viewport: SIZE, steps: STEPS, phase: args.phase, serverArgs, osd: args.osd || null, format: args.format || null, detail: args.detail || null, driver: args.playwright ? 'playwright' : 'cdp' };
try {
  const textures = (await (await fetch(`${server.url}/api/v1/textures`)).json()).textures;
  const big = pickTexture(textures, args.texture);
  results.texture = { name: big.name, model: big.model, width: big.width, height: big.height };
  const views = session(big, STEPS);
  const panStart = { zoom: 1, x: 20_000, y: 60_000 };
  const url = `${server.url}/?texture=${big.id}&zoom=0.01&x=50000&y=50000${args.format ? `&format=${args.format}` : ''}${args.detail ? `&detail=${args.detail}` : ''}`;
  results.server = {};

  // Cold: fresh server, fresh browser.
  let page = await openPage(url);
  await idle(page);
  let c0 = await serverCounters(server.url);
  results.cold = await measureViews(page, views, args.shots, 'cold');
  let c1 = await serverCounters(server.url);
  results.server.cold = serverDelta(c0, c1);
  if (args.passes === 'cold') await page.close();
  else {
    if (args.shots) await midLoadShots(page, args.shots, big);
    results.panCold = panSummary(await measurePan(page, panStart));
    await idle(page);
    results.panWarm = panSummary(await measurePan(page, panStart));
    // Warm browser: reload in the same profile (HTTP cache warm, OpenSeadragon's memory empty).
    await page.reload();
    await page.waitFor(() => window.vtexViewer && window.vtexViewer.state.item);
    await idle(page);
    results.warmBrowser = await measureViews(page, views, args.shots, 'warm-browser');
    await page.close();

    // Warm server: a fresh browser profile; every tile comes from the server's cache.
    page = await openPage(url);
    await idle(page);
    c0 = await serverCounters(server.url);
    if (args.profile) {
      await page.send('Profiler.enable');
      await page.send('Profiler.setSamplingInterval', { interval: 100 });
      await page.send('Profiler.start');
    }
    const endTrace = args['chrome-trace'] && (await page.startTrace(CHROME_TRACE_CATEGORIES));
    results.warmServer = await measureViews(page, views, args.shots, 'warm-server');
    if (endTrace) writeFileSync(args['chrome-trace'], await endTrace());
    if (args.profile) {
      const { profile } = await page.send('Profiler.stop');
      writeFileSync(args.profile, JSON.stringify(profile));
      results.profile = profileSummary(profile, STEPS);
    }
    c1 = await serverCounters(server.url);
    results.server.warmServer = serverDelta(c0, c1);
    // Warm viewer: back to the view before (its tiles still in OpenSeadragon's memory).
    results.warmViewer = await measureViews(page, views, args.shots, 'warm-viewer', { back: true });
    results.serverStats = await page.evaluate(() => window.vtexViewer.stats.snapshot());
    await page.close();
  }
} finally {
  await server.stop();
}

const f = (v) => v.toFixed(1);
console.log(`texture ${results.texture.name} (${results.texture.model}), ${results.viewport.width}×${results.viewport.height} browser viewport, ${STEPS} view changes (phase ${args.phase})${args.format ? `, ${args.format} tiles` : ''}${args.detail ? `, detail ${args.detail}` : ''}${args.osd ? `, OSD options ${args.osd}` : ''}, server ${serverArgs.join(' ')}, driven by ${results.driver}`);
console.log('| view change → every visible tile drawn: draw calls issued, p50 / p95 / max ms | rastered (the frame\'s main-thread work done), p50 / p95 / max ms | first complete coarse frame (the view drawn at most 3 levels coarser than the finest), p50 / p95 ms | tiles/view | requests/view | machine reference ms, before / after |');
console.log('|---|---|---|---|---|---|---|');
for (const [k, label] of [
  ['cold', 'cold (empty server cache, fresh browser)'],
  ['warmServer', 'warm server cache, fresh browser'],
  ['warmBrowser', 'warm browser HTTP cache (after reload)'],
  ['warmViewer', 'warm viewer: back to the previous view (tiles in memory)'],
]) {
  const r = results[k];
  if (!r) continue;
  console.log(`| ${label} | ${f(r.p50)} / ${f(r.p95)} / ${f(r.max)} | ${f(r.raster.p50)} / **${f(r.raster.p95)}** / ${f(r.raster.max)} | ${f(r.coarse.p50)} / **${f(r.coarse.p95)}** | ${r.tilesPerView.toFixed(1)} | ${r.requestsPerView.toFixed(1)} | ${r.cpuReferenceMs.map(f).join(' / ')} |`);
}
console.log('(machine reference: a fixed piece of JS timed in this process before and after the pass; lower is a faster machine)');
console.log(`\n| continuous pan, ${PAN_SPEED} px/frame for ${PAN_SECONDS} s at level 0 | frames | p50 ms | p95 ms | max ms | > 33 ms | > 50 ms | tiles |`);
console.log('|---|---|---|---|---|---|---|---|');
for (const [k, label] of [
  ['panCold', 'cold'],
  ['panWarm', 'warm (same path again)'],
]) {
  const r = results[k];
  if (!r) continue;
  console.log(`| ${label} | ${r.n} | ${f(r.p50)} | ${f(r.p95)} | ${f(r.max)} | ${r.over33} | ${r.over50} | ${r.tiles} |`);
}
// Mpx drawn: the drawn tiles' rectangles on the canvas.
console.log('\n| canvas per view change | tiles drawn | Mpx drawn |');
console.log('|---|---|---|');
for (const [k, label] of [
  ['cold', 'cold'],
  ['warmServer', 'warm server'],
  ['warmBrowser', 'warm browser'],
  ['warmViewer', 'warm viewer'],
]) {
  if (!results[k]) continue;
  const c = results[k].canvasPerView;
  const n = (v, scale = 1) => (v === null ? '–' : (v / scale).toFixed(scale === 1 ? 1 : 2));
  console.log(`| ${label} | ${n(c.drawnTiles)} | ${n(c.drawnPixels, 1e6)} |`);
}
for (const [k, label] of [
  ['cold', 'server, cold pass'],
  ['warmServer', 'server, warm-server pass'],
]) {
  const d = results.server[k];
  if (!d) continue;
  const levels = Object.entries(d.missesByLevel).map(([l, n]) => `L${l}: ${n}`).join(', ') || 'none';
  console.log(`\n${label}: ${d.syntheses} syntheses, mean ${Number.isFinite(d.synthMeanMs) ? f(d.synthMeanMs) : '–'} ms; misses by level ${levels}`);
}
if (args.trace) {
  for (const [k, label] of [
    ['cold', 'cold'],
    ['warmServer', 'warm server'],
    ['warmBrowser', 'warm browser'],
    ['warmViewer', 'warm viewer'],
  ]) {
    if (results[k]) console.log(formatBreakdown(label, results[k].breakdowns));
  }
}
if (results.profile) {
  const p = results.profile;
  console.log(`\nwarm-server pass, main thread per view (DevTools CPU profile ${args.profile}): ${f(p.msPerView)} ms, of it idle ${f(p.idle)}, JS ${f(p.js)}, garbage collection ${f(p.gc)}, browser work outside JS "(program)" ${f(p.program)}`);
  console.log(`top JS self time, ms per view: ${p.top.map(([k, v]) => `${k} ${v}`).join('; ')}`);
}
if (args.json) writeFileSync(args.json, JSON.stringify(results, null, 2));
