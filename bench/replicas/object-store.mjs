// Textures no replica has seen, through nginx: 3 replicas on one data directory beside 3
// replicas on one object-store bucket (Garage, each replica with its own empty data
// directory), the same nginx configuration (docker/nginx.conf) in front of both, in one run.
//   flock /tmp/vtex-bench.lock node bench/replicas/object-store.mjs [--textures 12] [--seconds 8]
// first tile: a bundle made offline (`vtex create`) is put straight into the store (a file
// copied in, an object put), then its first tile asked through nginx — the replica finds the
// bundle, reads, checks and loads it, and renders; one texture at a time, p50 / p95.
// cold tiles/s: wrk over distinct level-0 JPEG tiles of another such texture (its info asked
// first, through nginx), every request missing every cache.
import { execFileSync } from 'node:child_process';
import { copyFileSync, mkdtempSync, readFileSync, renameSync, rmSync } from 'node:fs';
import { cpus, loadavg, tmpdir } from 'node:os';
import { join } from 'node:path';
import { parseArgs } from 'node:util';
import { startGarage } from '../../tests/replicas/garage.mjs';
import { ROOT, startTopology, VTEX_BIN } from '../../tests/replicas/topology.mjs';

const { values: args } = parseArgs({
  options: {
    textures: { type: 'string', default: '12' },
    seconds: { type: 'string', default: '8' },
    connections: { type: 'string', default: '16' },
  },
});
const PREFIX = 'encodings';

/** `count` chaos mosaics (65,536², 1024 × 1024 blocks of the model's example sample), each of its
 * own name, hence its own id, written as `<tag>-<i>.vtex`: { id, path }. */
function makeBundles(dir, count, tag) {
  execFileSync(VTEX_BIN, ['models', 'chaos-mosaic', '--example-dir', dir], { encoding: 'utf8' });
  const example = JSON.parse(execFileSync(VTEX_BIN, ['models', 'chaos-mosaic', '--json'], { encoding: 'utf8' })).example;
  const params = JSON.stringify({ ...example.params, tiles_x: 1024, tiles_y: 1024 });
  const inputs = Object.keys(example.inputs).flatMap((name) => ['--input', `${name}=${join(dir, `chaos-mosaic-${name}.png`)}`]);
  return Array.from({ length: count }, (_, i) => {
    const path = join(dir, `${tag}-${i}.vtex`);
    const id = execFileSync(VTEX_BIN, ['create', '--model', 'chaos-mosaic', '--name', `unseen ${tag} ${i} ${Date.now()}`, '--params', params, ...inputs, '--out', path], {
      encoding: 'utf8',
    }).trim();
    return { id, path };
  });
}

function wrk(url, scriptArgs) {
  const out = execFileSync('wrk', ['-t2', `-c${args.connections}`, `-d${args.seconds}s`, '-s', join(ROOT, 'bench', 'replicas', 'cold.lua'), url, '--', ...scriptArgs], {
    encoding: 'utf8',
  });
  const rate = Number(out.match(/Requests\/sec:\s+([\d.]+)/)[1]);
  const errors = Number((out.match(/Non-2xx or 3xx responses: (\d+)/) || [0, 0])[1]);
  return { rate, errors, mean: out.match(/Latency\s+(\S+)/)[1] };
}

const quantile = (xs, q) => [...xs].sort((a, b) => a - b)[Math.min(xs.length - 1, Math.floor(q * xs.length))];

/** Puts each bundle into the topology's store with `put`, then times its first tile through nginx. */
async function measure(name, topo, put, bundles) {
  const firsts = [];
  for (const b of bundles.slice(1)) {
    put(b);
    const t0 = performance.now();
    const r = await fetch(`${topo.url}/api/v1/textures/${b.id}/tiles/0/5/7.jpg`);
    const body = Buffer.from(await r.arrayBuffer());
    if (r.status !== 200) throw new Error(`${name}: first tile of ${b.id}: ${r.status} ${body}`);
    firsts.push(performance.now() - t0);
  }
  put(bundles[0]);
  const info = await (await fetch(`${topo.url}/api/v1/textures/${bundles[0].id}`)).json();
  const across = Math.ceil(Math.min(info.width, info.height) / info.tile_size);
  const cold = wrk(topo.url, [`/api/v1/textures/${bundles[0].id}/tiles/0`, String(across)]);
  return { name, firsts, cold };
}

const scratch = mkdtempSync(join(tmpdir(), 'vtex-bench-unseen-'));
const count = Number(args.textures) + 1;
const results = [];
try {
  const forDir = makeBundles(scratch, count, 'dir');
  const forBucket = makeBundles(scratch, count, 'bucket');
  console.log(
    `== ${new Date().toISOString()} ${execFileSync('git', ['rev-parse', '--short', 'HEAD'], { cwd: ROOT, encoding: 'utf8' }).trim()} ` +
      `unseen textures through nginx, ${cpus().length} cores, load ${loadavg()[0].toFixed(2)}, ${count - 1} first tiles, wrk -t2 -c${args.connections} -d${args.seconds}s`,
  );
  {
    const topo = await startTopology({ replicas: 3 });
    try {
      // Copied in as an operator should: under a temporary name, then renamed.
      const copyIn = (b) => {
        const tmp = join(topo.dataDir, `.tmp-bench-${b.id}.vtex`);
        copyFileSync(b.path, tmp);
        renameSync(tmp, join(topo.dataDir, `${b.id}.vtex`));
      };
      results.push(await measure('shared data directory', topo, copyIn, forDir));
    } finally {
      await topo.stop();
    }
  }
  {
    const garage = await startGarage();
    const topo = await startTopology({ replicas: 3, store: `s3://${garage.bucket}/${PREFIX}`, env: garage.env });
    try {
      results.push(await measure('object store (Garage)', topo, (b) => garage.putObject(`${PREFIX}/${b.id}.vtex`, readFileSync(b.path)), forBucket));
    } finally {
      await topo.stop();
      await garage.stop();
    }
  }
} finally {
  rmSync(scratch, { recursive: true, force: true });
}
for (const r of results) {
  console.log(
    `${r.name}, 3 replicas: first tile of an unseen texture p50 ${quantile(r.firsts, 0.5).toFixed(1)} ms, p95 ${quantile(r.firsts, 0.95).toFixed(1)} ms; ` +
      `cold ${r.cold.rate.toFixed(0)} tiles/s (mean ${r.cold.mean}, non-2xx ${r.cold.errors})`,
  );
}
