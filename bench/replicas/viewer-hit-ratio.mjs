// nginx's hit ratio for the viewer's traffic: the viewer bench (bench/viewer/bench.mjs, a
// seeded pan-and-zoom session in headless Chromium, four passes over the same views) run twice
// against nginx in front of 3 replicas (tests/replicas/topology.mjs), counting nginx's cache
// status of every tile batch and tile request of each run from its access log.
//   flock /tmp/vtex-bench.lock node bench/replicas/viewer-hit-ratio.mjs [bench.mjs flags…]
import { execFileSync } from 'node:child_process';
import { writeFileSync } from 'node:fs';
import { loadavg } from 'node:os';
import { join } from 'node:path';
import { ROOT, startTopology } from '../../tests/replicas/topology.mjs';

const topo = await startTopology({ replicas: 3 });
const counts = (lines) => {
  const c = {};
  for (const l of lines.filter((x) => x.includes('/tiles'))) {
    const s = (l.match(/cache=(\S+)/) || [0, '?'])[1];
    c[s] = (c[s] || 0) + 1;
  }
  return c;
};
try {
  console.log(`== ${new Date().toISOString()} viewer session through nginx + 3 replicas, load ${loadavg()[0].toFixed(2)}`);
  let seen = 0;
  for (const run of [1, 2]) {
    execFileSync('node', [join(ROOT, 'bench', 'viewer', 'bench.mjs'), ...process.argv.slice(2)], {
      env: { ...process.env, VTEX_URL: topo.url },
      stdio: ['ignore', 'ignore', 'inherit'],
    });
    const lines = topo.accessLog().split('\n').filter(Boolean);
    const c = counts(lines.slice(seen));
    if (process.env.ACCESS_LOG) writeFileSync(process.env.ACCESS_LOG, lines.join('\n'));
    seen = lines.length;
    const total = Object.values(c).reduce((a, b) => a + b, 0);
    console.log(`run ${run}: ${total} tile requests through nginx, cache ${JSON.stringify(c)}, hit ratio ${((100 * (c.HIT || 0)) / total).toFixed(1)}%`);
  }
} finally {
  await topo.stop();
}
