// Per-stage timing of view changes for the measured session (`bench.mjs --trace`).
//
// In the page, `installTracer` wraps the viewer's loading path from outside (the viewer itself
// carries no tracing code) and records for every tile (keyed by its single-tile URL, which
// OpenSeadragon uses as its name), in performance.now() time:
//   want     OpenSeadragon first asked its image loader for the tile (ImageLoader.addJob)
//   start    the tile source took the job (TileSource.downloadTileBatchStart)
//   rt       Resource Timing of the batched request that carried it: requestStart,
//            responseStart (the batch's first byte), responseEnd
//   arrived  its frame was complete in JS (what the tile source notes in job.userData, with
//            the batch's URL and the server's hit or miss)
//   ready    the tile's pixels were handed to OpenSeadragon (job.finish)
//   drawn    the first frame that drew it (tile-drawn)
// and for every frame the time spent in OpenSeadragon's update and draw.
// In Node, `viewBreakdown` turns one view's records into stage durations.

/** Runs in the page (serialised by Playwright): hooks the open viewer. Idempotent per page. */
export function installTracer() {
  if (window.__vtexTrace) return;
  const { viewer, state } = window.vtexViewer;
  const now = () => performance.now();
  const tiles = new Map();
  const frames = [];
  const T = { tiles, frames };
  window.__vtexTrace = T;
  const rec = (src) => {
    let r = tiles.get(src);
    if (!r) {
      r = { src };
      tiles.set(src, r);
    }
    return r;
  };

  const loader = viewer.imageLoader;
  const addJob = loader.addJob.bind(loader);
  loader.addJob = (options) => {
    const r = rec(options.src);
    if (r.want === undefined) r.want = now();
    return addJob(options);
  };

  // OpenSeadragon starts a view's jobs together, as one batch (tilesource.js).
  const hookSource = (source) => {
    if (!source || source.__traced) return;
    source.__traced = true;
    const startBatch = source.downloadTileBatchStart.bind(source);
    source.downloadTileBatchStart = (batchJob) => {
      for (const job of batchJob.jobs) {
        const r = rec(job.src);
        r.start = now();
        r.starts = (r.starts || 0) + 1;
        const finish = job.finish.bind(job);
        job.finish = (data, request, dataType) => {
          r.ready = now();
          const u = job.userData;
          Object.assign(r, { batch: u.batchUrl, arrived: u.arrived, cache: u.cache });
          return finish(data, request, dataType);
        };
      }
      return startBatch(batchJob);
    };
  };
  hookSource(state.item && state.item.source);
  viewer.world.addHandler('add-item', (e) => hookSource(e.item.source));

  viewer.addHandler('tile-drawn', (e) => {
    const r = tiles.get(e.tile.getUrl());
    if (r && r.ready !== undefined && r.drawn === undefined) r.drawn = now();
  });

  // Long animation frames (> 50 ms of main-thread work around one frame), with what ran.
  T.loaf = [];
  try {
    new PerformanceObserver((list) => {
      for (const e of list.getEntries()) {
        T.loaf.push({
          t: e.startTime,
          duration: e.duration,
          render: e.renderStart ? e.startTime + e.duration - e.renderStart : 0,
          blocking: e.blockingDuration,
          scripts: (e.scripts || []).map((s) => ({ d: s.duration, what: `${s.invokerType} ${s.invoker}`.slice(0, 80) })),
        });
      }
    }).observe({ type: 'long-animation-frame', buffered: false });
  } catch {
    // not supported: no long-frame attribution
  }

  const world = viewer.world;
  const update = world.update.bind(world);
  const draw = world.draw.bind(world);
  let frame = null;
  world.update = (changed) => {
    const t = now();
    const out = update(changed);
    frame = { t, update: now() - t, draw: 0 };
    frames.push(frame);
    return out;
  };
  world.draw = () => {
    const t = now();
    draw();
    if (frame) frame.draw = now() - t;
  };
}

/**
 * Runs in the page: the records of tiles wanted in [t0, t1] (with their Resource Timing), the
 * frames in that span, then forgets both so the next view starts clean.
 */
export function collectTrace({ t0, t1 }) {
  const T = window.__vtexTrace;
  const origin = location.origin;
  // The tile Worker fetches the batches: the tile source keeps their timing (tilesource.js).
  const { state } = window.vtexViewer;
  const timings = state.item && state.item.source.vtexTimings;
  const tiles = [];
  for (const [src, r] of T.tiles) {
    if (r.want === undefined || r.want < t0 || r.want > t1) continue;
    const e = r.batch && timings ? timings.get(new URL(r.batch, origin).href) : null;
    tiles.push({
      ...r,
      rt: e ? { fetchStart: e.fetchStart, requestStart: e.requestStart, responseStart: e.responseStart, responseEnd: e.responseEnd, transferSize: e.transferSize } : null,
    });
  }
  const frames = T.frames.filter((f) => f.t >= t0 && f.t <= t1);
  const loaf = T.loaf.filter((e) => e.t + e.duration >= t0 && e.t <= t1);
  T.loaf = T.loaf.filter((e) => e.t > t1);
  T.tiles.clear();
  T.frames.length = 0;
  return { tiles, frames, loaf };
}

const STAGES = [
  // [name, description, from, to] — per tile, each a difference of two recorded times
  ['queue', 'asked by OSD → taken by the tile source', (r) => r.want, (r) => r.start],
  ['connect', 'taken → its batch sent (microtask flush, browser queue, connection)', (r) => r.start, (r) => r.rt && r.rt.requestStart],
  ['server', "sent → the batch's first byte (server time + loopback)", (r) => r.rt && r.rt.requestStart, (r) => r.rt && r.rt.responseStart],
  ['stream', "batch's first byte → this tile's frame complete in JS (frames before it, syntheses)", (r) => r.rt && r.rt.responseStart, (r) => r.arrived],
  ['decode', 'frame in JS → pixels handed to OSD', (r) => r.arrived, (r) => r.ready],
  ['draw', 'pixels ready → first frame drawing it', (r) => r.ready, (r) => r.drawn],
];

/** Stage durations of one view: per tile, and along the tile that was drawn last. */
export function viewBreakdown(view) {
  const { t0, t1, tiles, frames } = view;
  const done = tiles.filter((r) => r.ready !== undefined && r.drawn !== undefined && r.rt);
  const perTile = {};
  for (const [name, , from, to] of STAGES) {
    perTile[name] = done.map((r) => to(r) - from(r)).filter((d) => Number.isFinite(d));
  }
  let critical = null;
  if (done.length) {
    const last = done.reduce((a, b) => (b.drawn > a.drawn ? b : a));
    critical = { wait: last.want - t0 };
    for (const [name, , from, to] of STAGES) critical[name] = to(last) - from(last);
    critical.after = t1 - last.drawn;
    // The network's view of the same batch: its first to its last byte received.
    critical.net = last.rt.responseEnd > 0 ? last.rt.responseEnd - last.rt.responseStart : NaN;
  }
  const firstWant = tiles.length ? Math.min(...tiles.map((r) => r.want)) - t0 : NaN;
  // When the view's last tile reached each stage (ms after the change), and when its frames ran:
  // a view is drawn in the first frame after `ready`.
  const last = (f) => {
    const v = done.map(f).filter(Number.isFinite);
    return v.length ? Math.max(...v) - t0 : NaN;
  };
  const milestones = {
    lastByte: last((r) => r.rt.responseEnd),
    arrived: last((r) => r.arrived),
    ready: last((r) => r.ready),
    frames: frames.map((f) => f.t - t0),
  };
  const levels = {};
  for (const r of tiles) {
    const m = r.src.match(/\/tiles\/(\d+)\//);
    if (m) levels[m[1]] = (levels[m[1]] || 0) + 1;
  }
  return {
    total: t1 - t0,
    // tiles whose request started (OSD may ask for more; the viewer's scheduler drops some)
    tiles: tiles.filter((r) => r.start !== undefined).length,
    requests: new Set(tiles.map((r) => r.batch).filter(Boolean)).size,
    levels,
    completed: done.length,
    abandoned: tiles.filter((r) => r.ready === undefined).length,
    misses: tiles.filter((r) => r.cache === 'miss').length,
    firstWant,
    frames: frames.length,
    jsMs: frames.reduce((a, f) => a + f.update + f.draw, 0),
    drawMs: frames.reduce((a, f) => a + f.draw, 0),
    maxFrameJs: frames.reduce((a, f) => Math.max(a, f.update + f.draw), 0),
    loafMs: (view.loaf || []).reduce((a, e) => a + e.duration, 0),
    loafRenderMs: (view.loaf || []).reduce((a, e) => a + e.render, 0),
    loafScripts: (view.loaf || []).flatMap((e) => e.scripts),
    gaps: frames.slice(1).map((f, i) => f.t - frames[i].t),
    milestones,
    perTile,
    critical,
  };
}

function q(values, p) {
  if (!values.length) return NaN;
  const s = [...values].sort((a, b) => a - b);
  return s[Math.min(s.length - 1, Math.max(0, Math.ceil(p * s.length) - 1))];
}
const mean = (v) => (v.length ? v.reduce((a, b) => a + b, 0) / v.length : NaN);

/** Markdown tables summarising the breakdowns of one pass. */
export function formatBreakdown(label, breakdowns) {
  const f = (v) => (Number.isFinite(v) ? v.toFixed(1) : '–');
  const out = [];
  out.push(`\n${label}: per tile (all tiles requested during the ${breakdowns.length} view changes)`);
  out.push('| stage | p50 ms | p95 ms | mean ms |');
  out.push('|---|---|---|---|');
  for (const [name, what] of STAGES) {
    const all = breakdowns.flatMap((b) => b.perTile[name]);
    out.push(`| ${name} (${what}) | ${f(q(all, 0.5))} | ${f(q(all, 0.95))} | ${f(mean(all))} |`);
  }
  const crit = breakdowns.filter((b) => b.critical);
  const gaps = breakdowns.flatMap((b) => b.gaps);
  out.push(`\n${label}: frame intervals while loading: p50 ${f(q(gaps, 0.5))} ms, p95 ${f(q(gaps, 0.95))} ms, max ${f(Math.max(...gaps))} ms`);
  out.push(`${label}: long animation frames per view: ${f(mean(breakdowns.map((b) => b.loafMs)))} ms (of it rendering ${f(mean(breakdowns.map((b) => b.loafRenderMs)))} ms)`);
  const byWhat = new Map();
  for (const s of breakdowns.flatMap((b) => b.loafScripts)) byWhat.set(s.what, (byWhat.get(s.what) || 0) + s.d);
  const top = [...byWhat].sort((a, b) => b[1] - a[1]).slice(0, 6);
  out.push(`${label}: scripts in long frames, ms per view: ${top.map(([w, d]) => `${w}: ${f(d / breakdowns.length)}`).join('; ') || '–'}`);
  const ms = (k) => breakdowns.map((b) => b.milestones[k]).filter(Number.isFinite);
  out.push(
    `${label}: a view's last tile, ms after the change, p50 / p95: last byte ${f(q(ms('lastByte'), 0.5))} / ${f(q(ms('lastByte'), 0.95))}, frame complete in the Worker ${f(q(ms('arrived'), 0.5))} / ${f(q(ms('arrived'), 0.95))}, handed to OpenSeadragon ${f(q(ms('ready'), 0.5))} / ${f(q(ms('ready'), 0.95))}`,
  );
  out.push(`\n${label}: per view, along the tile drawn last (mean over views; p95 view time ${f(q(breakdowns.map((b) => b.total), 0.95))} ms)`);
  out.push('| view total | → first ask | → last tile asked | queue | connect | server | stream | (of it network first → last byte) | decode | draw | → detected | frames | JS in OSD update+draw | of it draw | tiles | requests | misses |');
  out.push('|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|');
  const m = (k) => f(mean(crit.map((b) => b.critical[k])));
  out.push(
    `| ${f(mean(breakdowns.map((b) => b.total)))} | ${f(mean(breakdowns.map((b) => b.firstWant).filter(Number.isFinite)))} | ${m('wait')} | ${m('queue')} | ${m('connect')} | ${m('server')} | ${m('stream')} | ${m('net')} | ${m('decode')} | ${m('draw')} | ${m('after')} | ${f(mean(breakdowns.map((b) => b.frames)))} | ${f(mean(breakdowns.map((b) => b.jsMs)))} | ${f(mean(breakdowns.map((b) => b.drawMs)))} | ${f(mean(breakdowns.map((b) => b.tiles)))} | ${f(mean(breakdowns.map((b) => b.requests)))} | ${f(mean(breakdowns.map((b) => b.misses)))} |`,
  );
  return out.join('\n');
}
