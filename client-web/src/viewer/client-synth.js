// The viewer's client mode (`?synth=client`, or the Synthesis control): the texture's encoding
// is fetched once and every tile is synthesized in this browser, by Workers each running the
// WebAssembly module of the texture's model (workers/synth-tiles.js over shared/vtex-synth.js),
// byte for byte the server's tile.
// Once the encoding is in, panning, zooming and animation need no server at all.
//
// A ClientSynth serves the tile sources of one texture (every animation frame): tilesource.js
// hands it OpenSeadragon's jobs (loadJobs, abortJob) instead of sending them to the server.

import { sourceTile } from './pyramid.js';
import { fetchOk, getJson } from '../shared/http.js';
import { moduleFile } from '../shared/vtex-synth.js';

/** Synthesis Workers: one per core, at most four. */
export const WORKERS = Math.max(1, Math.min(4, globalThis.navigator?.hardwareConcurrency || 2));

/** Each model's module compiled once per page, for every texture of that model and every Worker. */
const compiled = new Map();

/**
 * The synthesis module of `model` (beside the viewer's files, where client-web/build.mjs copies
 * it), compiled; fetched once per page and model, while the encoding is fetched.
 */
export function loadModule(model, stats) {
  if (!compiled.has(model)) {
    const url = new URL(moduleFile(model), document.baseURI).href;
    const compiling = fetchOk(url, 'the synthesis module').then(async (response) => {
      // Streaming compilation compiles while the bytes arrive; it needs the wasm media type,
      // which a static file server may not send.
      const streaming = response.headers.get('content-type')?.startsWith('application/wasm');
      const module = await (streaming ? WebAssembly.compileStreaming(response) : response.arrayBuffer().then((b) => WebAssembly.compile(b)));
      count(url, stats);
      return module;
    });
    compiled.set(model, compiling);
    compiling.catch(() => compiled.delete(model)); // a failed fetch may be retried by the next texture
  }
  return compiled.get(model);
}

/** Counts the transfer of `url` (its Resource Timing entry; `bytes` when there is none) in `stats`. */
function count(url, stats, bytes = 0) {
  const timing = performance.getEntriesByName(url).at(-1);
  stats.resource(timing || { transferSize: bytes, decodedBodySize: bytes });
}

/** Fetches `url`'s bytes, counting them in `stats`. */
async function fetchBytes(url, what, stats) {
  const bytes = await (await fetchOk(url, what)).arrayBuffer();
  count(url, stats, bytes.byteLength);
  return bytes;
}

export class ClientSynth {
  /**
   * Starts synthesizing texture `info` (the server's info: id, name, tile_size) from the
   * encoding at `encodingUrl`. `ready` resolves once every Worker has it open, or rejects with
   * a message that says why client synthesis is impossible.
   */
  constructor(info, { encodingUrl = `api/v1/textures/${encodeURIComponent(info.id)}/encoding`, stats }) {
    this.info = info;
    this.workers = [];
    /** Tiles asked for and not answered: key → { resolve, reject, worker }. */
    this.pending = new Map();
    this.nextKey = 1;
    this.closed = false;
    this.ready = this.start(new URL(encodingUrl, document.baseURI).href, stats).catch((e) => {
      this.close();
      throw new Error(`Client synthesis of “${info.name}” is not possible: ${e.message}`);
    });
  }

  async start(encodingUrl, stats) {
    const [bundle, module] = await Promise.all([fetchBytes(encodingUrl, 'the encoding', stats), loadModule(this.info.model, stats)]);
    if (this.closed) throw new Error('closed');
    const opened = [];
    for (let i = 0; i < WORKERS; i++) {
      const worker = new Worker(new URL('../workers/synth-tiles.js', import.meta.url), { type: 'module' });
      worker.load = 0;
      this.workers.push(worker);
      opened.push(
        new Promise((resolve, reject) => {
          worker.onmessage = ({ data }) => {
            if (data.type === 'opened') resolve(data.info);
            else if (data.type === 'failed') reject(new Error(data.error));
            else this.answer(worker, data);
          };
          worker.onerror = (e) => {
            const error = new Error(`a synthesis worker failed: ${e.message || 'it could not start'}`);
            reject(error);
            this.failWorker(worker, error);
          };
        }),
      );
      worker.postMessage({ type: 'open', module, bundle: bundle.slice(0), tileSize: this.info.tile_size });
    }
    const [got] = await Promise.all(opened);
    if (got.id !== this.info.id) {
      throw new Error(`the encoding received is not this texture's: its content id is ${got.id}, expected ${this.info.id}`);
    }
    return got;
  }

  /**
   * Tile (x, y) of vtex level `level` at `frame`: { promise, cancel }. The promise resolves with
   * { bitmap, ms } — or { bytes, width, height } when `raw` — and rejects with the reason.
   */
  tile(level, x, y, frame, { raw = false } = {}) {
    const key = this.nextKey++;
    let cancelled = false;
    const promise = this.ready.then(
      () =>
        new Promise((resolve, reject) => {
          if (cancelled || this.closed) return reject(new Error('cancelled'));
          const worker = this.workers.reduce((a, b) => (b.load < a.load ? b : a));
          worker.load++;
          this.pending.set(key, { resolve, reject, worker });
          worker.postMessage({ type: 'tile', key, level, x, y, frame, raw });
        }),
    );
    const cancel = () => {
      cancelled = true;
      const p = this.pending.get(key);
      if (!p) return;
      this.pending.delete(key);
      p.worker.load--;
      p.worker.postMessage({ type: 'cancel', key });
      p.reject(new Error('cancelled'));
    };
    return { promise, cancel };
  }

  /** A Worker's answer for a tile. */
  answer(worker, data) {
    const p = this.pending.get(data.key);
    if (!p) {
      data.bitmap?.close(); // cancelled meanwhile
      return;
    }
    this.pending.delete(data.key);
    worker.load--;
    if (data.error) p.reject(new Error(data.error));
    else p.resolve(data);
  }

  failWorker(worker, error) {
    for (const [key, p] of this.pending) {
      if (p.worker !== worker) continue;
      this.pending.delete(key);
      p.reject(error);
    }
    this.workers = this.workers.filter((w) => w !== worker);
    worker.terminate();
    if (this.workers.length === 0) this.closed = true;
  }

  /** Starts OpenSeadragon's `jobs` of the tile source of `context` (tilesource.js). */
  loadJobs(jobs, { info, frame, stats, inFlight }) {
    for (const job of jobs) {
      stats.started();
      inFlight.add(job);
      const t0 = performance.now();
      const t = sourceTile(info, job.tile);
      const request = this.tile(t.level, t.x, t.y, frame);
      job.userData = { ...job.userData, cancel: request.cancel };
      request.promise.then(
        ({ bitmap }) => {
          if (!inFlight.delete(job)) return bitmap.close();
          stats.loadedTile(performance.now() - t0, 0, null);
          job.finish(bitmap, null, 'imageBitmap');
        },
        (e) => {
          if (!inFlight.delete(job)) return;
          stats.failedTile(e.message);
          job.fail(e.message, null);
        },
      );
    }
  }

  /** Gives up `job`: its tile is no longer wanted. */
  abortJob(job, { inFlight, stats }) {
    if (!inFlight.delete(job)) return;
    job.userData.cancel();
    stats.abortedTile();
  }

  /** Stops the Workers; tiles not answered yet fail. */
  close() {
    this.closed = true;
    for (const [, p] of this.pending) p.reject(new Error('client synthesis stopped'));
    this.pending.clear();
    for (const w of this.workers) w.terminate();
    this.workers = [];
  }
}

/**
 * The description of a static export (`vtex export-web`), whose index.html names it in
 * `<meta name="vtex-export" content="…">`: { textures: [server-style info], encodings: { id →
 * bundle URL } }. Null when the page is served by vtex (no such meta).
 */
export async function staticExport() {
  const meta = document.querySelector('meta[name="vtex-export"]');
  if (!meta) return null;
  const url = new URL(meta.content, document.baseURI).href;
  return getJson(url, "the export's description");
}
