// An OpenSeadragon tile source over the vtex tile API. The tiles OpenSeadragon asks for in one
// update (OpenSeadragon's tile batching) go out as the metatiles that hold them (pyramid.js
// metatilesOf): aligned blocks that every viewer over the same area asks for alike, so a cache
// in front of the server shares them and a consistent hash spreads them over replicas. Each is
// fetched and its wanted tiles turned into ImageBitmaps by a Worker (workers/fetch-tiles.js) and handed to OpenSeadragon as
// data type "imageBitmap", which the viewer's drawer draws as it is (osd-adapter.js). Each tile
// reports what the server says about it (cache hit or miss) and how long it took. Formats: png /
// webp (lossless), jpg (lossy, smallest) and rgba (raw: no decoding, the fastest on a fast link).
// In client mode the tiles are synthesized in the page instead (client-synth.js): no request.

import { inPyramid, metatilesOf, metatileUrl, sourceTile, tileUrl, vtexLevel } from './pyramid.js';
import { MAX_BATCH, tileKey } from '../shared/batch.js';

/**
 * Makes the tile source for texture `info` (the server's info JSON) at animation `frame`.
 * `stats` is a TileStats that every download reports to. With `synth` (a ClientSynth of
 * `info`), tiles are synthesized in the page and `format` is not used.
 */
export function createTileSource(OSD, info, { frame = 0, format = 'png', stats, synth = null }) {
  const loader = synth ? null : tileLoader(stats);
  const inFlight = new Set();
  const context = { loader, info, frame, format, stats, inFlight };
  const load = synth ? (jobs, c) => synth.loadJobs(jobs, c) : loadMetatiles;
  const abort = synth ? (job, c) => synth.abortJob(job, c) : abortJob;
  const source = new OSD.TileSource({
    width: info.width,
    height: info.height,
    tileSize: info.tile_size,
    tileOverlap: 0,
    minLevel: 0,
    maxLevel: info.levels - 1,
    vtexInfo: info,
    vtexFrame: frame,
    vtexFormat: format,

    getTileUrl(level, x, y) {
      // OSD only asks for tiles that tileExists() accepted; null would be a bug upstream.
      return tileUrl(info, vtexLevel(info, level), x, y, frame, format);
    },

    tileExists(level, x, y) {
      return inPyramid(info, vtexLevel(info, level), x, y);
    },

    // Tiles are opaque: OSD may then skip drawing coarser levels under a complete finer one.
    hasTransparency() {
      return false;
    },

    // The jobs OpenSeadragon stages while it updates the view (every tile the view needs) go
    // out together once the update's task is over, as the metatiles that hold them. The navigator has an image loader of
    // its own: its jobs make batches of their own.
    batchEnabled() {
      return true;
    },

    batchCompatible(other) {
      return other === source;
    },

    batchMaxJobs() {
      return MAX_BATCH;
    },

    batchTimeout() {
      return 0;
    },

    downloadTileBatchStart(batchJob) {
      load(batchJob.jobs, context);
    },

    downloadTileBatchAbort(batchJob) {
      for (const job of batchJob.jobs) abort(job, context);
    },

    // One job on its own: OpenSeadragon retries a failed batch's tiles one by one.
    downloadTileStart(job) {
      load([job], context);
    },

    downloadTileAbort(job) {
      abort(job, context);
    },
  });
  // Jobs started and neither finished, failed nor aborted.
  source.vtexInFlight = inFlight;
  // Resource Timing of the batches by URL (the Worker's; bench/viewer/trace.mjs).
  source.vtexTimings = loader ? loader.timings : new Map();
  return source;
}

/**
 * Gives up `job` (it is no longer wanted): its tile's frame is then ignored, and the request is
 * aborted (the server stops making its tiles) once none of its tiles is wanted.
 */
function abortJob(job, { inFlight, stats }) {
  if (!inFlight.delete(job)) return; // never started, or already finished
  const data = job.userData;
  data.done = true;
  stats.abortedTile();
  const batch = data.batch;
  if (batch && !data.settled && --batch.live === 0) batch.controller.abort();
}

/**
 * The page's end of the tile Worker (workers/fetch-tiles.js), one Worker for all tile sources
 * (a texture switched, an animation frame loaded behind the visible one): batches by id, each
 * { onTile, onEnd }. Resource Timing entries of the batches (which the page does not see: the Worker
 * fetches them) go to `stats` (the latest tile source's; the page has one) and to `timings`
 * (by URL, for bench/viewer/trace.mjs), shifted to the page's clock.
 */
let shared = null;
function tileLoader(stats) {
  if (shared) {
    shared.stats = stats;
    return shared;
  }
  const worker = new Worker(new URL('../workers/fetch-tiles.js', import.meta.url), { type: 'module' });
  const loader = { worker, stats, batches: new Map(), nextId: 1, timings: new Map() };
  worker.onmessage = ({ data }) => {
    if (data.type === 'timing') {
      const e = data.entry;
      for (const k of ['fetchStart', 'requestStart', 'responseStart', 'responseEnd']) e[k] = pageTime(e[k]);
      loader.stats.resource(e);
      loader.timings.set(e.name, e);
      if (loader.timings.size > 256) loader.timings.delete(loader.timings.keys().next().value);
      return;
    }
    const batch = loader.batches.get(data.id);
    if (data.type === 'tiles') {
      for (const t of data.tiles) {
        if (batch) batch.onTile(t);
        else if (t.bitmap) t.bitmap.close(); // a batch already given up
      }
    } else if (data.type === 'end' && batch) {
      loader.batches.delete(data.id);
      batch.onEnd(data.error);
    }
  };
  worker.onerror = (e) => {
    const message = `the tile worker failed: ${e.message || 'could not start'}`;
    for (const batch of loader.batches.values()) batch.onEnd(message);
    loader.batches.clear();
  };
  shared = loader;
  return loader;
}

/** An epoch time from the Worker (performance.timeOrigin + now there) on the page's clock. */
function pageTime(t) {
  return t - performance.timeOrigin;
}

/**
 * Fetches the tiles of `jobs` as the metatiles that hold them, coarsest first (loadMetatile).
 */
function loadMetatiles(jobs, context) {
  const { info, frame, format } = context;
  const tiles = jobs.map((job) => ({ ...sourceTile(info, job.tile), job }));
  for (const block of metatilesOf(info, tiles)) {
    const url = metatileUrl(info, block.level, block.x, block.y, frame, format);
    loadMetatile(
      block.tiles.map((t) => t.job),
      url,
      context,
    );
  }
}

/**
 * Fetches metatile `url` (through `loader`'s Worker, which decodes only the tiles `jobs` want)
 * and finishes each job with its tile's ImageBitmap. Jobs aborted meanwhile are skipped; a
 * request with none left is aborted. A tile the response does not carry (error, cut-off
 * stream) fails its job with the reason.
 */
function loadMetatile(jobs, relativeUrl, { loader, info, format, stats, inFlight }) {
  const id = loader.nextId++;
  const controller = { abort: () => loader.worker.postMessage({ type: 'abort', id }) };
  // Jobs by tile: two tiled images of one source may want the same tile.
  const byKey = new Map();
  const batch = { controller, live: jobs.length };
  const tiles = [];
  const t0 = performance.now();
  for (const job of jobs) {
    job.userData = job.userData || {};
    Object.assign(job.userData, { t0, done: false, settled: false, batch });
    inFlight.add(job);
    stats.started();
    const t = sourceTile(info, job.tile);
    const key = tileKey(t.level, t.x, t.y);
    if (byKey.has(key)) byKey.get(key).push(job);
    else {
      byKey.set(key, [job]);
      tiles.push(t);
    }
  }
  // Absolute: the Worker would resolve a relative URL against its own script's.
  const url = new URL(relativeUrl, document.baseURI).href;
  for (const job of jobs) job.userData.batchUrl = url; // for bench/viewer/trace.mjs
  stats.batchStarted();
  // Ends a job once, with its bitmap or the reason it has none.
  const end = (job, bitmap, error) => {
    const data = job.userData;
    if (data.done) {
      if (bitmap) bitmap.close();
      return;
    }
    data.done = true;
    inFlight.delete(job);
    if (bitmap) {
      stats.loadedTile(performance.now() - data.t0, data.length, data.cache);
      job.finish(bitmap, null, 'imageBitmap');
    } else {
      stats.failedTile(error);
      job.fail(error, null);
    }
  };
  // A job is settled once its tile came (or the batch failed): it no longer counts as live.
  const settle = (job) => {
    if (job.userData.settled) return;
    job.userData.settled = true;
    const t = sourceTile(info, job.tile);
    const key = tileKey(t.level, t.x, t.y);
    const left = (byKey.get(key) || []).filter((j) => j !== job);
    if (left.length) byKey.set(key, left);
    else byKey.delete(key);
    if (!job.userData.done) batch.live--;
  };
  const onTile = (t) => {
    const waiting = byKey.get(tileKey(t.level, t.x, t.y));
    if (!waiting) {
      if (t.bitmap) t.bitmap.close();
      onEnd(`the metatile answered tile ${t.level}/${t.x}/${t.y}, which it did not ask for`);
      return;
    }
    // Jobs sharing a tile each get a bitmap of their own (OpenSeadragon's cache frees each):
    // copies of the same pixels, taken before any job could close the first.
    const copies = waiting.slice(1).map(() => (t.bitmap ? createImageBitmap(t.bitmap) : null));
    waiting.forEach((job, i) => deliverTo(job, t, i === 0 ? t.bitmap : copies[i - 1]));
  };
  const deliverTo = (job, t, bitmap) => {
    settle(job);
    if (t.error) {
      end(job, null, t.error);
      return;
    }
    Object.assign(job.userData, { arrived: pageTime(t.arrived), cache: t.cache, length: t.length });
    Promise.resolve(bitmap).then(
      (b) => end(job, b),
      (e) => end(job, null, `tile ${t.level}/${t.x}/${t.y}: ${e.message}`),
    );
  };
  const onEnd = (error) => {
    loader.batches.delete(id);
    if (error === 'aborted') return; // every tile left was aborted
    const message = error || 'the metatile ended without this tile';
    for (const job of [...byKey.values()].flat()) {
      settle(job);
      end(job, null, `${message} (${job.src})`);
    }
  };
  loader.batches.set(id, { onTile, onEnd });
  const want = tiles.map((t) => tileKey(t.level, t.x, t.y));
  loader.worker.postMessage({ type: 'load', id, url, format, want });
}
