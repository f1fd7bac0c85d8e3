// Summarises a Chromium trace written by `bench.mjs --chrome-trace FILE` (the warm-server pass):
// where each process's threads spent their time, what the page's main thread and the display
// compositor did (time and count by trace event, not counting events nested in it; the
// compositor's `SoftwareRenderer::DoDrawQuad` are the quads it drew), and the canvas flushes
// (the software raster of OpenSeadragon's drawing), and the JavaScript V8 sampled on the page's
// main thread and the tile Worker's thread, by function.
//
//   node bench/viewer/chrome-trace-summary.mjs FILE [--views 60] [--top 15] [--view N]
//
// --views divides the totals by the number of view changes the trace covers (bench: --steps).
// --view N prints the timeline of view change N (from 0) instead: every thread's tasks of
// 0.15 ms and more from the change (bench.mjs marks it with console.timeStamp) to the next,
// in ms after the change, with the events that took most of each: where a view's time went,
// frame by frame.
import { readFileSync } from 'node:fs';
import { parseArgs } from 'node:util';

const { values: args, positionals } = parseArgs({
  allowPositionals: true,
  options: { views: { type: 'string', default: '60' }, top: { type: 'string', default: '15' }, view: { type: 'string' } },
});
if (positionals.length !== 1) {
  console.error('usage: node bench/viewer/chrome-trace-summary.mjs FILE [--views N] [--top N] [--view N]');
  process.exit(2);
}
const VIEWS = Number(args.views);
const TOP = Number(args.top);
const trace = JSON.parse(readFileSync(positionals[0], 'utf8'));
const events = Array.isArray(trace) ? trace : trace.traceEvents;

const processes = new Map();
const threads = new Map();
for (const e of events) {
  if (e.ph !== 'M') continue;
  if (e.name === 'process_name') processes.set(e.pid, e.args.name);
  if (e.name === 'thread_name') threads.set(`${e.pid}/${e.tid}`, e.args.name);
}
const threadName = (key) => `${processes.get(Number(key.split('/')[0])) || '?'} · ${threads.get(key) || '?'}`;

// Complete events ('X') by thread, in start order (an enclosing event before what it encloses).
const byThread = new Map();
for (const e of events) {
  if (e.ph !== 'X' || e.dur === undefined) continue;
  const key = `${e.pid}/${e.tid}`;
  if (!byThread.has(key)) byThread.set(key, []);
  byThread.get(key).push(e);
}
for (const list of byThread.values()) list.sort((a, b) => a.ts - b.ts || b.dur - a.dur);

/** ms a thread ran tasks: the events no other event of the thread encloses. */
function busy(list) {
  let total = 0;
  let end = -Infinity;
  for (const e of list) {
    if (e.ts >= end) {
      total += e.dur;
      end = e.ts + e.dur;
    } else if (e.ts + e.dur > end) {
      total += e.ts + e.dur - end;
      end = e.ts + e.dur;
    }
  }
  return total / 1000;
}

/** By event name: { ms, count }, each event's time minus the events nested in it. */
function selfTimes(list) {
  const self = new Map();
  const entry = (name) => self.get(name) || self.set(name, { ms: 0, count: 0 }).get(name);
  const stack = [];
  for (const e of list) {
    while (stack.length && stack.at(-1).ts + stack.at(-1).dur <= e.ts) stack.pop();
    if (stack.length) entry(stack.at(-1).name).ms -= e.dur / 1000;
    const own = entry(e.name);
    own.ms += e.dur / 1000;
    own.count++;
    stack.push(e);
  }
  return self;
}

const f = (v) => v.toFixed(1);
if (args.view !== undefined) {
  printView(Number(args.view));
  process.exit(0);
}
const rows = [...byThread].map(([key, list]) => [threadName(key), busy(list)]).sort((a, b) => b[1] - a[1]);
console.log(`| thread | busy ms | per view (${VIEWS}) |`);
console.log('|---|---|---|');
for (const [name, ms] of rows.slice(0, TOP)) console.log(`| ${name} | ${f(ms)} | ${f(ms / VIEWS)} |`);

for (const [thread, label] of [
  ['CrRendererMain', "the page's main thread"],
  ['VizCompositorThread', 'the display compositor'],
]) {
  // The busiest of the threads so named (the page's renderer, not the about:blank one).
  const found = [...byThread].filter(([key]) => threads.get(key) === thread).sort((a, b) => busy(b[1]) - busy(a[1]))[0];
  if (!found) continue;
  const self = [...selfTimes(found[1])].sort((a, b) => b[1].ms - a[1].ms);
  console.log(`\n${label} (${threadName(found[0])}), time by event, nested events not counted:`);
  console.log(`| event | ms | per view | count |`);
  console.log('|---|---|---|---|');
  for (const [name, { ms, count }] of self.slice(0, TOP)) console.log(`| ${name} | ${f(ms)} | ${f(ms / VIEWS)} | ${count} |`);
}

const flushes = events
  .filter((e) => e.ph === 'X' && e.name === 'Canvas2DResourceProviderSharedImage::ProduceCanvasResource')
  .map((e) => e.dur / 1000)
  .sort((a, b) => a - b);
if (flushes.length) {
  const sum = flushes.reduce((a, b) => a + b, 0);
  const q = (p) => flushes[Math.min(flushes.length - 1, Math.ceil(p * flushes.length) - 1)];
  console.log(
    `\ncanvas flushes: ${flushes.length}, ${f(sum)} ms (${f(sum / VIEWS)} a view); per flush p50 ${f(q(0.5))}, p95 ${f(q(0.95))}, max ${f(flushes.at(-1))} ms`,
  );
}

// JavaScript as V8's sampler saw it (the trace's `disabled-by-default-v8.cpu_profiler` category):
// self time by function on the page's main thread and on the tile Worker's thread, where the
// trace events above show only "RunTask" for the Worker's script.
const samples = sampledJs();
for (const [thread, label] of [
  ['CrRendererMain', "the page's main thread"],
  ['DedicatedWorker thread', "the tile Worker's thread"],
]) {
  const found = [...samples].filter(([key]) => threads.get(key) === thread).sort((a, b) => b[1].busy - a[1].busy)[0];
  if (!found) continue;
  const [key, { self, busy: ms }] = found;
  console.log(`\n${label} (${threadName(key)}), JS sampled by V8: ${f(ms)} ms not idle (${f(ms / VIEWS)} a view), self time by function:`);
  console.log(`| function | ms | per view |`);
  console.log('|---|---|---|');
  for (const [name, t] of [...self].sort((a, b) => b[1] - a[1]).slice(0, TOP)) console.log(`| ${name} | ${f(t)} | ${f(t / VIEWS)} |`);
}

/** Per thread key: { self: Map(function → ms), busy: ms } from the trace's V8 sample chunks. */
function sampledJs() {
  const profiles = new Map(); // pid/profile id → { key, nodes, samples, deltas }
  for (const e of events) {
    if (e.name === 'Profile') profiles.set(`${e.pid}/${e.id}`, { key: `${e.pid}/${e.tid}`, nodes: new Map(), samples: [], deltas: [] });
    if (e.name !== 'ProfileChunk') continue;
    const p = profiles.get(`${e.pid}/${e.id}`);
    const data = e.args && e.args.data;
    if (!p || !data) continue;
    for (const n of (data.cpuProfile && data.cpuProfile.nodes) || []) p.nodes.set(n.id, n);
    p.samples.push(...((data.cpuProfile && data.cpuProfile.samples) || []));
    p.deltas.push(...(data.timeDeltas || []));
  }
  const out = new Map();
  for (const p of profiles.values()) {
    const self = new Map();
    let total = 0;
    // A sample's time is the interval to the next one.
    for (let i = 0; i + 1 < p.samples.length; i++) {
      const frame = (p.nodes.get(p.samples[i]) || {}).callFrame || {};
      if (frame.functionName === '(idle)') continue;
      const where = frame.url ? ` ${frame.url.replace(/^.*\//, '')}:${frame.lineNumber + 1}` : '';
      const name = `${frame.functionName || '(anonymous)'}${where}`;
      const ms = p.deltas[i + 1] / 1000;
      self.set(name, (self.get(name) || 0) + ms);
      total += ms;
    }
    if (total > 0) out.set(p.key, { self, busy: total });
  }
  return out;
}

/** The events of `list` that no other event of it encloses, in order. */
function topLevel(list) {
  const out = [];
  let end = -Infinity;
  for (const e of list) {
    if (e.ts >= end) {
      out.push(e);
      end = e.ts + e.dur;
    }
  }
  return out;
}

/** Timeline of view change `n`: each thread's tasks from its change to the next change. */
function printView(n) {
  const marks = events
    .filter((e) => e.name === 'TimeStamp' && JSON.stringify(e.args || {}).includes('vtex view change'))
    .map((e) => e.ts)
    .sort((a, b) => a - b);
  if (n < 0 || n >= marks.length) {
    console.error(`--view ${n}: the trace marks ${marks.length} view changes (bench.mjs --chrome-trace)`);
    process.exit(2);
  }
  const t0 = marks[n];
  const t1 = n + 1 < marks.length ? marks[n + 1] : Infinity;
  const at = (ts) => f((ts - t0) / 1000);
  console.log(`view change ${n}: ms after the change, tasks of 0.15 ms and more, until the next change${Number.isFinite(t1) ? ` (${at(t1)} ms)` : ''}`);
  for (const [key, list] of byThread) {
    const tasks = topLevel(list).filter((e) => e.ts + e.dur > t0 && e.ts < t1);
    const shown = tasks.filter((e) => e.dur >= 150);
    if (!shown.length) continue;
    const ms = tasks.reduce((a, e) => a + Math.min(e.ts + e.dur, t1) - Math.max(e.ts, t0), 0) / 1000;
    console.log(`\n${threadName(key)}: busy ${f(ms)} ms`);
    for (const e of shown) {
      const inside = list.filter((c) => c !== e && c.ts >= e.ts && c.ts + c.dur <= e.ts + e.dur).sort((a, b) => b.dur - a.dur);
      const what = inside.slice(0, 3).map((c) => `${c.name} ${f(c.dur / 1000)}`).join(', ');
      console.log(`  ${at(e.ts).padStart(6)} +${f(e.dur / 1000).padStart(5)}  ${e.name}${what ? `  [${what}]` : ''}`);
    }
  }
}
