// nginx's cache for a second user: the viewer bench's cold pass (bench/viewer/bench.mjs, a seeded
// pan-and-zoom session in headless Chromium) by a first user, then by a second user over the
// same places — every view shifted by a random fraction of a view, through another window size
// — against nginx in front of 3 replicas (tests/replicas/topology.mjs). Counts the tile traffic
// (metatiles, tiles, batches) of each user from nginx's access log by cache status, in requests
// and in bytes.
//   flock /tmp/vtex-bench.lock node bench/replicas/viewer-hit-ratio.mjs [bench.mjs flags…]
import { execFileSync } from 'node:child_process';
import { writeFileSync } from 'node:fs';
import { loadavg } from 'node:os';
import { join } from 'node:path';
import { ROOT, startTopology } from '../../tests/replicas/topology.mjs';

const USERS = [
  ['first user, 1280×800', []],
  ['second user, 1024×640, every view shifted', ['--shift', '7', '--width', '1024', '--height', '640']],
];

/** Requests and bytes of tile traffic by cache status, from access log lines (docker/nginx.conf). */
function counts(lines) {
  const c = {};
  for (const l of lines) {
    const m = l.match(/"GET \S*\/(?:metatiles\/|tiles)\S* HTTP\/[\d.]+" \d+ (\d+) cache=(\S+)/);
    if (!m) continue;
    const s = (c[m[2]] ||= { requests: 0, bytes: 0 });
    s.requests += 1;
    s.bytes += Number(m[1]);
  }
  return c;
}

const topo = await startTopology({ replicas: 3 });
try {
  console.log(`== ${new Date().toISOString()} viewer sessions through nginx + 3 replicas, load ${loadavg()[0].toFixed(2)}`);
  let seen = 0;
  for (const [who, flags] of USERS) {
    execFileSync('node', [join(ROOT, 'bench', 'viewer', 'bench.mjs'), '--passes', 'cold', ...flags, ...process.argv.slice(2)], {
      env: { ...process.env, VTEX_URL: topo.url },
      stdio: ['ignore', 'inherit', 'inherit'],
    });
    const lines = topo.accessLog().split('\n').filter(Boolean);
    const c = counts(lines.slice(seen));
    if (process.env.ACCESS_LOG) writeFileSync(process.env.ACCESS_LOG, lines.join('\n'));
    seen = lines.length;
    const sum = (k) => Object.values(c).reduce((a, s) => a + s[k], 0);
    const share = (k) => ((100 * ((c.HIT && c.HIT[k]) || 0)) / sum(k)).toFixed(1);
    console.log(`${who}: ${sum('requests')} tile requests, ${(sum('bytes') / 1e6).toFixed(2)} MB; from nginx's cache ${share('requests')} % of requests, ${share('bytes')} % of bytes; ${JSON.stringify(c)}`);
  }
} finally {
  await topo.stop();
}
