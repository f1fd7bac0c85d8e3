// Does nginx's response buffering hold back a streamed tile batch? Time to the first body bytes
// and to the end of batches of uncached tiles, through nginx (docker/nginx.conf, and the same
// with `proxy_buffering` switched the other way in the tiles' location) beside the same
// batches asked of a replica directly, in the same run.
//   flock /tmp/vtex-bench.lock node bench/replicas/batch-first-frame.mjs [--batches 12] [--tiles 8] [--format png]
// The order-independent flagship: its tiles take tens of milliseconds each, so a batch's
// frames leave the replica spread over its whole duration.
import { execFileSync } from 'node:child_process';
import { readFileSync } from 'node:fs';
import { loadavg } from 'node:os';
import { parseArgs } from 'node:util';
import { NGINX_CONF, ROOT, startTopology } from '../../tests/replicas/topology.mjs';

const { values: args } = parseArgs({
  options: {
    batches: { type: 'string', default: '12' },
    tiles: { type: 'string', default: '8' },
    format: { type: 'string', default: 'png' },
  },
});
const batches = Number(args.batches);
const tiles = Number(args.tiles);

/** ms to the response headers, to the first body bytes and to the end of one request. */
async function timeBatch(url) {
  const t0 = performance.now();
  const r = await fetch(url);
  const headers = performance.now() - t0;
  if (r.status !== 200) throw new Error(`${r.status} ${url}: ${await r.text()}`);
  const reader = r.body.getReader();
  let first = null;
  let bytes = 0;
  for (;;) {
    const { done, value } = await reader.read();
    if (done) break;
    first ??= performance.now() - t0;
    bytes += value.length;
  }
  return { headers, first, end: performance.now() - t0, bytes };
}

const median = (xs) => [...xs].sort((a, b) => a - b)[Math.floor(xs.length / 2)];

/** Batches of distinct level-0 tiles, none asked before: row `row` onwards. */
function batchPaths(texture, row) {
  return Array.from({ length: batches }, (_, b) => {
    const list = Array.from({ length: tiles }, (_, i) => `0/${i}/${row + b}`).join(',');
    return `/api/v1/textures/${texture.id}/tiles?format=${args.format}&tiles=${list}`;
  });
}

async function run(variant, editConf) {
  const topo = await startTopology({ replicas: 3, editConf });
  try {
    const list = await (await fetch(`${topo.url}/api/v1/textures`)).json();
    const texture = list.textures.find((t) => t.name.startsWith('Order-independent A'));
    // Loaded on every replica before timing.
    for (const r of topo.replicas) await (await fetch(`${r.url}/api/v1/textures/${texture.id}/tiles/0/200/200.png`)).arrayBuffer();
    const direct = [];
    const proxied = [];
    const viaNginx = batchPaths(texture, 0);
    const toReplica = batchPaths(texture, 100);
    for (let b = 0; b < batches; b++) {
      proxied.push(await timeBatch(topo.url + viaNginx[b]));
      direct.push(await timeBatch(topo.replicas[b % 3].url + toReplica[b]));
    }
    const line = (name, xs) =>
      `${name}: headers ${median(xs.map((x) => x.headers)).toFixed(0)} ms, first bytes ${median(xs.map((x) => x.first)).toFixed(0)} ms, ` +
      `end ${median(xs.map((x) => x.end)).toFixed(0)} ms (medians of ${xs.length}, ${median(xs.map((x) => x.bytes))} bytes)`;
    console.log(`${variant}\n  ${line('through nginx', proxied)}\n  ${line('replica directly', direct)}`);
  } finally {
    await topo.stop();
  }
}

const commit = execFileSync('git', ['rev-parse', '--short', 'HEAD'], { cwd: ROOT, encoding: 'utf8' }).trim();
console.log(`== ${new Date().toISOString()} ${commit} batch first frame, ${batches} batches of ${tiles} uncached ${args.format} tiles, load ${loadavg()[0].toFixed(2)}`);
const tilesLocation = 'location /api/v1/textures/ {';
const switched = (conf) => {
  if (!conf.includes(tilesLocation)) throw new Error(`docker/nginx.conf has no "${tilesLocation}"`);
  const on = /\n\s*proxy_buffering off;/.test(conf);
  return on
    ? conf.replace(/\n\s*proxy_buffering off;/, '')
    : conf.replace(tilesLocation, `${tilesLocation}\n            proxy_buffering off;`);
};
const current = /proxy_buffering off;/.test(readFileSync(NGINX_CONF, 'utf8'));
await run(`docker/nginx.conf as it is (proxy_buffering ${current ? 'off' : 'on'})`, (c) => c);
await run(`switched (proxy_buffering ${current ? 'on' : 'off'})`, switched);
