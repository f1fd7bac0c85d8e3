// Client synthesis: one texture's encoding, fetched once, opened by Workers each running the
// WebAssembly module (workers/synth-tiles.js over vtex-synth.js), which render its tiles and
// regions byte for byte as the server does. The viewer's client mode (viewer/client-synth.js)
// and the 3D world's pages (world/) are made this way.

import { fetchOk } from './http.js';
import { moduleFile } from './vtex-synth.js';

/** Synthesis Workers a texture: one per core, at most four. */
export const WORKERS = Math.max(1, Math.min(4, globalThis.navigator?.hardwareConcurrency || 2));

/** The modules compiled once per page, for every texture and Worker: URL → promise. */
const compiled = new Map();

/**
 * The synthesis module for textures of `model`, compiled; fetched once per page. A page calls it
 * as soon as it knows it will synthesize, so the download overlaps the rest of its start-up.
 * `stats.resource(timing)`, when given, counts the transfer.
 */
export function loadModule(stats, model) {
  const url = new URL(moduleFile(model), document.baseURI).href;
  if (!compiled.has(url)) {
    const module = fetchOk(url, 'the synthesis module').then(async (response) => {
      // Streaming compilation compiles while the bytes arrive; it needs the wasm media type,
      // which a static file server may not send.
      const streaming = response.headers.get('content-type')?.startsWith('application/wasm');
      const m = await (streaming ? WebAssembly.compileStreaming(response) : response.arrayBuffer().then((b) => WebAssembly.compile(b)));
      count(url, stats);
      return m;
    });
    module.catch(() => compiled.delete(url)); // a failed fetch may be retried by the next texture
    compiled.set(url, module);
  }
  return compiled.get(url);
}

/** Counts the transfer of `url` (its Resource Timing entry; `bytes` when there is none) in `stats`, if any. */
function count(url, stats, bytes = 0) {
  const timing = performance.getEntriesByName(url).at(-1);
  stats?.resource(timing || { transferSize: bytes, decodedBodySize: bytes });
}

/** Fetches `url`'s bytes, counting them in `stats`. */
async function fetchBytes(url, what, stats) {
  const bytes = await (await fetchOk(url, what)).arrayBuffer();
  count(url, stats, bytes.byteLength);
  return bytes;
}

export class SynthWorkers {
  /**
   * Starts synthesizing texture `info` (the server's info: id, name, model, tile_size) from the
   * encoding at `encodingUrl`, counting the fetches in `stats` (loadModule). `ready` resolves
   * once every Worker has it open, or rejects with a message that says why client synthesis is
   * impossible.
   */
  constructor(info, { encodingUrl = `api/v1/textures/${encodeURIComponent(info.id)}/encoding`, stats = null, workers = WORKERS } = {}) {
    this.info = info;
    this.workerCount = workers;
    this.workers = [];
    /** Jobs asked for and not answered: key → { resolve, reject, worker }. */
    this.pending = new Map();
    this.nextKey = 1;
    this.closed = false;
    this.ready = this.start(new URL(encodingUrl, document.baseURI).href, stats).catch((e) => {
      this.close();
      throw new Error(`Client synthesis of “${info.name}” is not possible: ${e.message}`);
    });
  }

  async start(encodingUrl, stats) {
    // The Workers start (their scripts load) while the encoding and the module download.
    const bytes = Promise.all([fetchBytes(encodingUrl, 'the encoding', stats), loadModule(stats, this.info.model)]);
    const opened = [];
    for (let i = 0; i < this.workerCount; i++) {
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
    }
    const allOpened = Promise.all(opened);
    allOpened.catch(() => {}); // a Worker failing to start is reported below, once the bytes are in
    const [bundle, module] = await bytes;
    if (this.closed) throw new Error('closed');
    for (const worker of this.workers) worker.postMessage({ type: 'open', module, bundle: bundle.slice(0), tileSize: this.info.tile_size });
    const [got] = await allOpened;
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
    return this.job({ type: 'tile', level, x, y, frame, raw });
  }

  /**
   * The region of `level` at (x, y), `width` × `height`, at `frame`, as RGBA rows: { promise,
   * cancel }, the promise resolving with { bytes, width, height }.
   */
  region({ level, x, y, width, height, frame = 0 }) {
    return this.job({ type: 'region', level, x, y, width, height, frame });
  }

  /** Sends `message` to the least loaded Worker once the texture is open: { promise, cancel }. */
  job(message) {
    const key = this.nextKey++;
    let cancelled = false;
    const promise = this.ready.then(
      () =>
        new Promise((resolve, reject) => {
          if (cancelled || this.closed) return reject(new Error('cancelled'));
          const worker = this.workers.reduce((a, b) => (b.load < a.load ? b : a));
          worker.load++;
          this.pending.set(key, { resolve, reject, worker });
          worker.postMessage({ ...message, key });
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

  /** A Worker's answer to a job. */
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

  /** Stops the Workers; jobs not answered yet fail. */
  close() {
    this.closed = true;
    for (const [, p] of this.pending) p.reject(new Error('client synthesis stopped'));
    this.pending.clear();
    for (const w of this.workers) w.terminate();
    this.workers = [];
  }
}
