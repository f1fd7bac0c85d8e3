// Chromium driven over a bare DevTools pipe, for the measured session (`bench.mjs`).
//
// Playwright enables DevTools' Network domain on every page (it reports every request and
// response to its driver), which adds Chromium CPU to every request — a large share of what
// the request itself costs (`request-cost.mjs` measures both drivers) — so the bench would
// partly measure the instrumentation. Here only Runtime.evaluate,
// Page.reload and Page.captureScreenshot are sent: the page runs as it would for a user.
import { spawn } from 'node:child_process';
import { mkdtempSync, rmSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { CHROMIUM, CHROMIUM_ARGS, exited } from '../../tests/browser/lib.mjs';

/**
 * Launches headless Chromium (fresh profile, same flags as tests/browser/lib.mjs) with `url` open;
 * `initScript` (source text) runs in every document before the page's own scripts.
 */
export async function launchBare(url, { width = 1280, height = 800, initScript } = {}) {
  const profile = mkdtempSync(join(tmpdir(), 'vtex-chromium-bare-'));
  const proc = spawn(
    CHROMIUM,
    [
      ...CHROMIUM_ARGS,
      '--force-device-scale-factor=1',
      `--window-size=${width},${height}`,
      `--user-data-dir=${profile}`,
      '--remote-debugging-pipe',
      'about:blank',
    ],
    { stdio: ['ignore', 'ignore', 'pipe', 'pipe', 'pipe'] },
  );
  let stderr = '';
  proc.stderr.on('data', (d) => (stderr = (stderr + d).slice(-4000)));
  const toChrome = proc.stdio[3];
  const fromChrome = proc.stdio[4];
  let id = 0;
  const pending = new Map();
  const listeners = new Map(); // event method → [fn]
  let buffer = '';
  fromChrome.on('data', (chunk) => {
    buffer += chunk.toString('utf8');
    let end;
    while ((end = buffer.indexOf('\0')) >= 0) {
      const message = JSON.parse(buffer.slice(0, end));
      buffer = buffer.slice(end + 1);
      if (message.method) for (const fn of listeners.get(message.method) || []) fn(message.params);
      const p = message.id !== undefined && pending.get(message.id);
      if (p) {
        pending.delete(message.id);
        if (message.error) p.reject(new Error(`${p.method}: ${message.error.message}`));
        else p.resolve(message.result);
      }
    }
  });
  proc.on('exit', () => {
    for (const p of pending.values()) p.reject(new Error(`chromium exited; stderr:\n${stderr}`));
    pending.clear();
  });
  const send = (method, params = {}, sessionId) =>
    new Promise((resolve, reject) => {
      const i = ++id;
      pending.set(i, { resolve, reject, method });
      toChrome.write(`${JSON.stringify({ id: i, method, params, ...(sessionId ? { sessionId } : {}) })}\0`);
    });

  const { targetInfos } = await send('Target.getTargets');
  const target = targetInfos.find((t) => t.type === 'page');
  const { sessionId } = await send('Target.attachToTarget', { targetId: target.targetId, flatten: true });
  const page = (method, params) => send(method, params, sessionId);
  // The page's viewport exactly width × height (as Playwright's `viewport`), whatever the window.
  await page('Emulation.setDeviceMetricsOverride', { width, height, deviceScaleFactor: 1, mobile: false });
  if (initScript) {
    // Without the Page domain enabled Chromium takes the script and never runs it.
    await page('Page.enable');
    await page('Page.addScriptToEvaluateOnNewDocument', { source: initScript });
  }
  await page('Page.navigate', { url });

  /** Runs `fn(arg)` in the page (awaiting a returned promise) and returns its JSON value. */
  async function evaluate(fn, arg, { truthy = false } = {}) {
    let expression = `(${fn.toString()})(${arg === undefined ? '' : JSON.stringify(arg)})`;
    if (truthy) expression = `Promise.resolve(${expression}).then((v) => !!v)`;
    let r;
    try {
      r = await page('Runtime.evaluate', { expression, awaitPromise: true, returnByValue: true });
    } catch (e) {
      e.message += ` (evaluating ${fn.toString().slice(0, 160).replace(/\s+/g, ' ')})`;
      throw e;
    }
    if (r.exceptionDetails) {
      const e = r.exceptionDetails;
      throw new Error(`in page: ${e.exception ? e.exception.description || e.exception.value : e.text}`);
    }
    return r.result.value;
  }

  /** Polls `fn(arg)` in the page every `interval` ms until it is truthy. */
  async function waitFor(fn, arg, { timeout = 60_000, interval = 50 } = {}) {
    const t0 = Date.now();
    for (;;) {
      try {
        if (await evaluate(fn, arg, { truthy: true })) return;
      } catch (e) {
        // the page may be between documents (navigation, reload: a pending promise is then
        // "collected")
        if (!/Execution context|Cannot find context|Promise was collected|in page/.test(String(e))) throw e;
      }
      if (Date.now() - t0 > timeout) throw new Error(`timed out after ${timeout} ms waiting for ${fn}`);
      await new Promise((r) => setTimeout(r, interval));
    }
  }

  return {
    evaluate,
    waitFor,
    /** Reloads and resolves once the new document runs (the old one is marked to tell them apart). */
    async reload() {
      await evaluate(() => (window.__vtexOldDocument = true));
      await page('Page.reload', {});
      await waitFor(() => !window.__vtexOldDocument && document.readyState !== 'loading');
    },
    /** Sends a DevTools command to the page's session (e.g. the Profiler domain). */
    send: page,
    /**
     * Starts a Chromium trace of every process (Tracing domain, browser session) with
     * `categories`; the returned function ends it and resolves to its JSON text.
     */
    async startTrace(categories) {
      await send('Tracing.start', { categories: categories.join(','), transferMode: 'ReturnAsStream' });
      return async () => {
        const complete = new Promise((resolve) => listeners.set('Tracing.tracingComplete', [resolve]));
        await send('Tracing.end');
        const { stream } = await complete;
        let text = '';
        for (;;) {
          const { data, eof, base64Encoded } = await send('IO.read', { handle: stream, size: 1 << 20 });
          text += base64Encoded ? Buffer.from(data, 'base64').toString('utf8') : data;
          if (eof) break;
        }
        await send('IO.close', { handle: stream });
        return text;
      };
    },
    async screenshot(path) {
      const { data } = await page('Page.captureScreenshot', { format: 'png' });
      writeFileSync(path, Buffer.from(data, 'base64'));
    },
    async close() {
      try {
        await send('Browser.close');
      } catch {
        // already gone
      }
      await exited(proc);
      rmSync(profile, { recursive: true, force: true });
    },
  };
}
