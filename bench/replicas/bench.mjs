// Tiles per second through nginx: 3 replicas on one data directory beside 1 replica, the same
// nginx configuration (docker/nginx.conf) in front of both, in the same run, with wrk.
//   flock /tmp/vtex-bench.lock node bench/replicas/bench.mjs [--seconds 10] [--connections 16]
// cold: distinct level-0 JPEG tiles (every request misses nginx's cache and the replicas');
// warm: 200 tiles primed first, then requested over and over (nginx cache hits).
import { execFileSync } from 'node:child_process';
import { loadavg, cpus } from 'node:os';
import { join } from 'node:path';
import { parseArgs } from 'node:util';
import { ROOT, startTopology } from '../../tests/replicas/topology.mjs';

const { values: args } = parseArgs({
  options: { seconds: { type: 'string', default: '10' }, connections: { type: 'string', default: '16' } },
});
const here = join(ROOT, 'bench', 'replicas');

function wrk(url, script, scriptArgs) {
  const out = execFileSync('wrk', ['-t2', `-c${args.connections}`, `-d${args.seconds}s`, '-s', join(here, script), url, '--', ...scriptArgs], {
    encoding: 'utf8',
  });
  const rate = Number(out.match(/Requests\/sec:\s+([\d.]+)/)[1]);
  const errors = (out.match(/Non-2xx or 3xx responses: (\d+)/) || [0, 0])[1];
  const latency = out.match(/Latency\s+(\S+)\s+(\S+)\s+(\S+)/);
  return { rate, errors: Number(errors), mean: latency[1] };
}

async function measure(replicas) {
  const topo = await startTopology({ replicas });
  try {
    const list = await (await fetch(`${topo.url}/api/v1/textures`)).json();
    const t = list.textures.filter((x) => x.model === 'chaos-mosaic').sort((a, b) => b.width - a.width)[0];
    const prefix = `/api/v1/textures/${t.id}/tiles/0`;
    const across = Math.ceil(t.width / t.tile_size);
    // The texture loaded on every replica before timing.
    for (const r of topo.replicas) await fetch(`${r.url}${prefix}/1/1.jpg`);
    const cold = wrk(topo.url, 'cold.lua', [prefix, String(across)]);
    for (let i = 0; i < 200; i++) await (await fetch(`${topo.url}${prefix}/${300 + (i % 20)}/${300 + Math.floor(i / 20)}.jpg`)).arrayBuffer();
    const warm = wrk(topo.url, 'warm.lua', [prefix, '200']);
    const log = topo.accessLog().split('\n');
    const hits = log.filter((l) => l.includes('cache=HIT')).length;
    return { replicas, cold, warm, hitShare: hits / log.filter((l) => l.includes('/tiles/')).length };
  } finally {
    await topo.stop();
  }
}

console.log(`== ${new Date().toISOString()} ${execFileSync('git', ['rev-parse', '--short', 'HEAD'], { cwd: ROOT, encoding: 'utf8' }).trim()} replicas bench, ${cpus().length} cores, load ${loadavg()[0].toFixed(2)}, wrk -t2 -c${args.connections} -d${args.seconds}s`);
for (const replicas of [1, 3]) {
  const m = await measure(replicas);
  console.log(
    `${replicas} replica(s) behind nginx: cold ${m.cold.rate.toFixed(0)} tiles/s (mean ${m.cold.mean}, non-2xx ${m.cold.errors}); ` +
      `warm ${m.warm.rate.toFixed(0)} tiles/s (mean ${m.warm.mean}, non-2xx ${m.warm.errors}); nginx cache hits ${(100 * m.hitShare).toFixed(1)}% of tile requests`,
  );
}
