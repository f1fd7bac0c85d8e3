// A cold view through nginx in front of 1 replica and of 3, in the same run: the viewer bench's
// cold pass (bench/viewer/bench.mjs, headless Chromium) against each topology
// (tests/replicas/topology.mjs, docker/nginx.conf: a consistent hash on the URL). A view's
// metatiles are distinct URLs, so the hash spreads them over the replicas.
//   flock /tmp/vtex-bench.lock node bench/replicas/viewer-cold.mjs [bench.mjs flags…, e.g. --texture cascade]
import { execFileSync } from 'node:child_process';
import { mkdtempSync, readFileSync } from 'node:fs';
import { loadavg, tmpdir } from 'node:os';
import { join } from 'node:path';
import { ROOT, startTopology } from '../../tests/replicas/topology.mjs';

const f = (v) => v.toFixed(1);
console.log(`== ${new Date().toISOString()} cold viewer sessions through nginx, 1 replica then 3, load ${loadavg()[0].toFixed(2)}`);
for (const replicas of [1, 3]) {
  const topo = await startTopology({ replicas });
  try {
    const json = join(mkdtempSync(join(tmpdir(), 'vtex-viewer-cold-')), 'bench.json');
    execFileSync('node', [join(ROOT, 'bench', 'viewer', 'bench.mjs'), '--passes', 'cold', '--json', json, ...process.argv.slice(2)], {
      env: { ...process.env, VTEX_URL: topo.url },
      stdio: ['ignore', 'ignore', 'inherit'],
    });
    const { texture, cold } = JSON.parse(readFileSync(json, 'utf8'));
    console.log(`${replicas} replica(s), ${texture.name}: cold view rastered p50 / p95 ${f(cold.raster.p50)} / ${f(cold.raster.p95)} ms, first complete coarse frame p50 / p95 ${f(cold.coarse.p50)} / ${f(cold.coarse.p95)} ms, ${f(cold.requestsPerView)} requests a view`);
  } finally {
    await topo.stop();
  }
}
