// A real S3-compatible object store on loopback for the object-store tests and benchmark:
// Garage (crates.io `garage`, installed by scripts/test under target/garage), one node, one
// bucket and one key, set up with its own CLI as its quick start does.
import { execFileSync, spawn } from 'node:child_process';
import { createHash, randomBytes } from 'node:crypto';
import { existsSync, mkdtempSync, readdirSync, readFileSync, rmSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { freePort, ROOT } from './topology.mjs';

export const GARAGE_BIN = process.env.GARAGE || join(ROOT, 'target', 'garage', 'bin', 'garage');
export const REGION = 'garage';
export const BUCKET = 'vtex';

/** Starts Garage; resolves once its bucket takes requests, with { endpoint, bucket, keyId,
 * secret, env (the AWS_* variables of a client), stop(), pause(), resume(), restart(),
 * putObject(key, bytes) } — the last through curl's own SigV4 signing. */
export async function startGarage() {
  if (!existsSync(GARAGE_BIN)) throw new Error(`${GARAGE_BIN} not found: scripts/test installs it (cargo install garage)`);
  const dir = mkdtempSync(join(tmpdir(), 'vtex-garage-'));
  const [rpc, s3] = [await freePort(), await freePort()];
  const conf = join(dir, 'garage.toml');
  writeFileSync(
    conf,
    [
      `metadata_dir = "${join(dir, 'meta')}"`,
      `data_dir = "${join(dir, 'data')}"`,
      'db_engine = "sqlite"',
      'replication_factor = 1',
      `rpc_bind_addr = "127.0.0.1:${rpc}"`,
      `rpc_public_addr = "127.0.0.1:${rpc}"`,
      `rpc_secret = "${randomBytes(32).toString('hex')}"`,
      '[s3_api]',
      `s3_region = "${REGION}"`,
      `api_bind_addr = "127.0.0.1:${s3}"`,
      'root_domain = ".s3.garage.localhost"',
      '',
    ].join('\n'),
  );
  const cli = (...args) => execFileSync(GARAGE_BIN, ['-c', conf, ...args], { encoding: 'utf8', stdio: ['ignore', 'pipe', 'pipe'] });
  let server = null;
  let log = '';
  const start = async () => {
    server = spawn(GARAGE_BIN, ['-c', conf, 'server'], { stdio: ['ignore', 'ignore', 'pipe'], env: { ...process.env, RUST_LOG: 'warn' } });
    server.stderr.on('data', (d) => {
      log = (log + d).slice(-8000);
    });
    server.exited = new Promise((res) => server.on('exit', (code, signal) => res({ code, signal })));
    // Up once its CLI reaches it over RPC.
    for (let t = 0; ; t++) {
      try {
        return cli('status');
      } catch (e) {
        if (server.exitCode !== null || t > 300) throw new Error(`garage did not start: ${e.stderr || e}\n${log}`);
        await new Promise((r) => setTimeout(r, 100));
      }
    }
  };
  const status = await start();
  const node = status.match(/^([0-9a-f]{16})\s/m)?.[1];
  if (!node) throw new Error(`no node id in garage status:\n${status}`);
  cli('layout', 'assign', '-z', 'dc1', '-c', '1G', node);
  cli('layout', 'apply', '--version', '1');
  const key = cli('key', 'create', 'vtex-test');
  const keyId = key.match(/Key ID:\s*(GK[0-9a-f]+)/)?.[1];
  const secret = key.match(/Secret key:\s*([0-9a-f]+)/)?.[1];
  if (!keyId || !secret) throw new Error(`no key in garage key create:\n${key}`);
  cli('bucket', 'create', BUCKET);
  cli('bucket', 'allow', '--read', '--write', '--owner', BUCKET, '--key', keyId);
  const endpoint = `http://127.0.0.1:${s3}`;
  const env = {
    AWS_ACCESS_KEY_ID: keyId,
    AWS_SECRET_ACCESS_KEY: secret,
    AWS_REGION: REGION,
    AWS_ENDPOINT_URL: endpoint,
    AWS_ALLOW_HTTP: 'true',
  };
  const garage = {
    endpoint,
    bucket: BUCKET,
    keyId,
    secret,
    env,
    log: () => log,
    /** Writes an object directly, as any S3 client would (path-style, signed by curl). */
    putObject(key, bytes) {
      execFileSync(
        'curl',
        ['-sSf', '--aws-sigv4', `aws:amz:${REGION}:s3`, '--user', `${keyId}:${secret}`, '-X', 'PUT',
          // S3 wants the payload's hash among the signed headers; curl signs what it is given.
          '-H', `x-amz-content-sha256: ${createHash('sha256').update(bytes).digest('hex')}`,
          '-H', 'content-type: application/octet-stream', '--data-binary', '@-', `${endpoint}/${BUCKET}/${key}`],
        { input: bytes },
      );
    },
    /** Freezes the server (SIGSTOP): connections open, nothing answers. Resolves once every
     * thread has stopped: a signal reaches a thread running elsewhere only when it next
     * enters the kernel, and until then it may still answer. */
    async pause() {
      server.kill('SIGSTOP');
      const tasks = `/proc/${server.pid}/task`;
      const stopped = () => readdirSync(tasks).every((t) => /^\d+ \(.*\) [tT] /s.test(readFileSync(`${tasks}/${t}/stat`, 'utf8')));
      for (let t = 0; !stopped(); t++) {
        if (t > 500) throw new Error('garage did not stop on SIGSTOP');
        await new Promise((r) => setTimeout(r, 2));
      }
    },
    resume: () => server.kill('SIGCONT'),
    /** Stops the server (SIGTERM, SIGKILL after 5 s) and waits for it to exit. */
    async kill() {
      server.kill('SIGCONT');
      server.kill('SIGTERM');
      const timer = setTimeout(() => server.kill('SIGKILL'), 5000);
      await server.exited;
      clearTimeout(timer);
    },
    /** Starts it again on the same data and addresses. */
    start,
    async stop() {
      if (server.exitCode === null && server.signalCode === null) await garage.kill();
      rmSync(dir, { recursive: true, force: true });
    },
  };
  return garage;
}
