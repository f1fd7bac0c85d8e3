// The topology of docker/compose.yaml on loopback: N `vtex serve` processes on one data
// directory, or on one object store (garage.mjs), behind Debian's nginx, run from
// docker/nginx.conf itself with only its upstream addresses, listen address and paths
// rewritten. Used by the replicas tests and the benchmark.
import { spawn } from 'node:child_process';
import { chmodSync, mkdirSync, mkdtempSync, readFileSync, rmSync, writeFileSync, existsSync } from 'node:fs';
import { createServer } from 'node:net';
import { tmpdir } from 'node:os';
import { dirname, join, resolve } from 'node:path';
import { createInterface } from 'node:readline';
import { fileURLToPath } from 'node:url';
import { NGINX_CONF, readNginxConf, rewrite } from '../../docker/nginx-conf.mjs';

export const ROOT = resolve(dirname(fileURLToPath(import.meta.url)), '..', '..');
export const VTEX_BIN = process.env.VTEX_BIN || join(ROOT, 'target', 'release', 'vtex');
export const NGINX = process.env.NGINX || '/usr/sbin/nginx';
export { NGINX_CONF };

/** A free loopback port (closed again before it is used: a brief race, loopback only). */
export async function freePort() {
  return new Promise((resolvePort, reject) => {
    const srv = createServer();
    srv.listen(0, '127.0.0.1', () => {
      const { port } = srv.address();
      srv.close(() => resolvePort(port));
    });
    srv.on('error', reject);
  });
}

/** docker/nginx.conf with its upstream servers at `upstreams` (host:port), listening on
 * `listen`, its paths under `dir`. */
export function nginxConf(upstreams, listen, dir) {
  let conf = readNginxConf();
  // Compose's replicas vtex-1…vtex-3: the first `upstreams.length` take these addresses, the
  // others are left out (a topology of fewer replicas, for the benchmark's baseline).
  let i = 0;
  conf = rewrite(conf, /\n\s*server vtex-\d+:8080/, (line) => {
    const addr = upstreams[i++];
    return addr ? line.replace(/vtex-\d+:8080/, addr) : '\n    #';
  }, 3);
  if (upstreams.length > 3) throw new Error('docker/nginx.conf names 3 replicas');
  // Addresses, not names: nothing to look up again (and the host's nginx may predate `resolve`).
  conf = rewrite(conf, /\n    include \/etc\/nginx\/resolver\.conf;/, '', 1);
  conf = rewrite(conf, / resolve /, ' ', 3);
  conf = rewrite(conf, /listen 80;/, `listen ${listen};`, 1);
  conf = rewrite(conf, /\/var\/run\/nginx\.pid/, join(dir, 'nginx.pid'), 1);
  conf = rewrite(conf, /\/var\/cache\/nginx/, join(dir, 'cache'), 6);
  conf = rewrite(conf, /access_log \/dev\/stdout/, `access_log ${join(dir, 'access.log')}`, 1);
  return conf;
}

/** Starts one `vtex serve` on `bind` (a free port by default); resolves with { url, addr,
 * dataDir, proc, stderr(), exited } once it listens. */
export async function startReplica(dataDir, { args = [], env = {}, bind = '127.0.0.1:0' } = {}) {
  if (!existsSync(VTEX_BIN)) throw new Error(`${VTEX_BIN} not found: run cargo build --release -p vtex-server`);
  const proc = spawn(VTEX_BIN, ['serve', '--bind', bind, '--data-dir', dataDir, ...args], {
    stdio: ['ignore', 'pipe', 'pipe'],
    env: { ...process.env, VTEX_LOG: 'warn', ...env },
  });
  let stderr = '';
  proc.stderr.on('data', (d) => {
    stderr = (stderr + d).slice(-8000);
  });
  const exited = new Promise((res) => proc.on('exit', (code, signal) => res({ code, signal })));
  const url = await new Promise((resolveUrl, reject) => {
    const timer = setTimeout(() => reject(new Error(`vtex did not listen within 120 s:\n${stderr}`)), 120_000);
    createInterface({ input: proc.stdout }).on('line', (line) => {
      const m = line.match(/^vtex listening on (http:\/\/\S+)/);
      if (m) {
        clearTimeout(timer);
        resolveUrl(m[1]);
      }
    });
    exited.then(({ code }) => {
      clearTimeout(timer);
      reject(new Error(`vtex exited with ${code} before listening:\n${stderr}`));
    });
  });
  return { url, addr: url.replace('http://', ''), dataDir, proc, exited, stderr: () => stderr };
}

/** Starts `replicas` vtex processes (the first alone, writing the demos; then the others) and
 * nginx in front, its configuration passed through `editConf` (a benchmark's variant). They
 * share one fresh data directory; or, given `store` (`s3://…`, its client configured by `env`),
 * only that object store, each with a data directory of its own for its copies. `restart(i)`
 * replaces replica i on its address; `stop()` ends them all and removes the files. */
export async function startTopology({ replicas = 3, env = {}, args = [], store = null, editConf = (conf) => conf } = {}) {
  const dir = mkdtempSync(join(tmpdir(), 'vtex-replicas-'));
  // nginx's workers run as an unprivileged user when started as root: they write the cache here.
  chmodSync(dir, 0o755);
  let dirs = 0;
  const dataDir = join(dir, 'data');
  const replicaDir = () => (store ? join(dir, `data-${dirs++}`) : dataDir);
  const replicaArgs = store ? [...args, '--store', store] : args;
  const nginxDir = join(dir, 'nginx');
  mkdirSync(join(nginxDir, 'cache'), { recursive: true });
  chmodSync(join(nginxDir, 'cache'), 0o777);
  const started = [await startReplica(replicaDir(), { args: replicaArgs, env })];
  started.push(
    ...(await Promise.all(
      Array.from({ length: replicas - 1 }, () =>
        startReplica(replicaDir(), { args: [...replicaArgs, '--no-demos'], env }),
      ),
    )),
  );
  const port = await freePort();
  const confPath = join(nginxDir, 'nginx.conf');
  writeFileSync(confPath, editConf(nginxConf(started.map((r) => r.addr), `127.0.0.1:${port}`, nginxDir)));
  const nginx = spawn(NGINX, ['-p', nginxDir, '-c', confPath, '-e', 'stderr', '-g', 'daemon off;'], {
    stdio: ['ignore', 'ignore', 'pipe'],
  });
  let nginxErr = '';
  nginx.stderr.on('data', (d) => {
    nginxErr = (nginxErr + d).slice(-8000);
  });
  const nginxExited = new Promise((res) => nginx.on('exit', (code) => res(code)));
  const url = `http://127.0.0.1:${port}`;
  for (let t = 0; ; t++) {
    try {
      if ((await fetch(`${url}/nginx-health`)).ok) break;
    } catch {
      // not listening yet
    }
    if (nginx.exitCode !== null || t > 200) throw new Error(`nginx did not start:\n${nginxErr}`);
    await new Promise((r) => setTimeout(r, 25));
  }
  return {
    url,
    dataDir,
    replicas: started,
    accessLog: () => readFileSync(join(nginxDir, 'access.log'), 'utf8'),
    nginxStderr: () => nginxErr,
    /** Stops replica `i` with SIGTERM (it drains) and starts another on its address, over a new
     * empty data directory of its own when there is an object store. */
    async restart(i) {
      const old = started[i];
      old.proc.kill('SIGTERM');
      await old.exited;
      started[i] = await startReplica(replicaDir(), { args: [...replicaArgs, '--no-demos'], env, bind: old.addr });
      return started[i];
    },
    async stop() {
      for (const r of started) if (r.proc.exitCode === null && r.proc.signalCode === null) r.proc.kill('SIGKILL');
      await Promise.all(started.map((r) => r.exited));
      if (nginx.exitCode === null) nginx.kill('SIGQUIT');
      await nginxExited;
      rmSync(dir, { recursive: true, force: true });
    },
  };
}
