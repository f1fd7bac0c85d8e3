// An OpenSeadragon tile source over the vtex tile API. Tiles are loaded in batches, one
// request for all the tiles a view needs (batch.js; a browser spends ~3 ms of CPU on every
// request, BENCHMARKS.md "Viewer"), fetched and turned into bitmaps by a Worker
// (tile-worker.js), and each tile reports what the server says about it (cache hit or miss)
// and how long it took. Formats: png / webp (lossless), jpg (lossy, smallest) and rgba (raw:
// no decoding, the fastest on a fast link).

import { inPyramid, tileUrl, vtexLevel } from './pyramid.js';
import { MAX_BATCH, batchUrl, tileKey } from './batch.js';

/**
 * Makes the tile source for texture `info` (the server's info JSON) at animation `frame`.
 * `stats` is a TileStats that every download reports to.
 */
export function createTileSource(OSD, info, { frame = 0, format = 'png', stats }) {
  const loader = tileLoader(stats);
  const maxLevel = info.levels - 1;
  const inFlight = new Set();
  let pending = [];
  const flush = () => {
    const jobs = pending;
    pending = [];
    const live = jobs.filter((job) => !job.userData.done);
    for (let i = 0; i < live.length; i += MAX_BATCH) {
      loadBatch(loader, info, live.slice(i, i + MAX_BATCH), { frame, format, stats });
    }
  };
  const source = new OSD.TileSource({
    width: info.width,
    height: info.height,
    tileSize: info.tile_size,
    tileOverlap: 0,
    minLevel: 0,
    maxLevel,
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

    // The jobs OpenSeadragon starts in one task (one update: every tile a view needs) go out
    // as one batched request, flushed in a microtask; each job finishes as its frame arrives.
    downloadTileStart(job) {
      const data = job.userData;
      data.done = false;
      data.t0 = performance.now();
      // Finishing twice (a frame after OSD's own timeout) would unbalance OSD's job count.
      const finish = job.finish.bind(job);
      job.finish = (result, request, error) => {
        if (data.finished) return;
        data.finished = true;
        data.done = true;
        inFlight.delete(job);
        finish(result, request, error);
      };
      inFlight.add(job);
      stats.started();
      pending.push(job);
      if (pending.length === 1) queueMicrotask(flush);
    },

    // The tile is no longer wanted (loader.js): its frame is ignored, and the request is
    // aborted (the server stops making its tiles) once none of its tiles is wanted.
    downloadTileAbort(job) {
      if (!inFlight.delete(job)) return; // never started (OSD's queue), or already finished
      const data = job.userData;
      data.done = true;
      stats.abortedTile();
      const batch = data.batch;
      if (batch && !data.settled && --batch.live === 0) batch.controller.abort();
    },

    // A tile arrives as `{ canvas: ImageBitmap }` (tileImage below): the canvas drawer draws
    // the bitmap as it would draw a tile's canvas.
    createTileCache(cache, image) {
      cache._data = image;
    },

    destroyTileCache(cache) {
      if (cache._data) releaseImage(cache._data);
      cache._data = null;
    },

    getTileCacheData(cache) {
      return cache._data;
    },

    getTileCacheDataAsImage(cache) {
      return cache._data && cache._data.canvas;
    },

    getTileCacheDataAsContext2D(cache) {
      return cache._data;
    },
  });
  // Jobs started and neither finished nor aborted (loader.js drops those a view left).
  source.vtexInFlight = inFlight;
  // Resource Timing of the batches by URL (the Worker's; bench/viewer/trace.mjs).
  source.vtexTimings = loader.timings;
  return source;
}

/**
 * A tile's pixels as the canvas drawer takes them: OpenSeadragon asks the tile source for a 2D
 * context and draws its `canvas` (`drawImage(ctx.canvas, …)`, sized by its width and height),
 * so an object whose `canvas` is the tile's ImageBitmap is drawn as is. An ImageBitmap, not a
 * canvas filled with `putImageData`: a new canvas costs the main thread ~0.3 ms a 256 px tile
 * to allocate and premultiply, the bitmap ~0.1 ms (BENCHMARKS.md "Viewer", ingest.mjs).
 */
function tileImage(bitmap) {
  return { canvas: bitmap };
}

/**
 * Frees a tile's pixels now rather than at the next garbage collection. OpenSeadragon then sets
 * the "canvas" to 0 × 0 (its way of freeing a canvas): it gets a plain stand-in instead.
 */
function releaseImage(image) {
  if (typeof image.canvas.close === 'function') image.canvas.close();
  image.canvas = { width: 0, height: 0 };
}

/**
 * The page's end of the tile Worker (tile-worker.js), one Worker for all tile sources (a texture
 * switched, an animation frame loaded behind the visible one): batches by id, each { onTile,
 * onEnd }. Resource Timing entries of the batches (which the page does not see: the Worker
 * fetches them) go to `stats` (the latest tile source's; the page has one) and to `timings`
 * (by URL, for bench/viewer/trace.mjs), shifted to the page's clock.
 */
let shared = null;
function tileLoader(stats) {
  if (shared) {
    shared.stats = stats;
    return shared;
  }
  const worker = new Worker(new URL('./tile-worker.js', import.meta.url), { type: 'module' });
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
 * Fetches the tiles of `jobs` in one request (through `loader`'s Worker) and finishes each job
 * as its tile arrives (in the server's completion order). Jobs aborted meanwhile are skipped; a
 * batch with none left is aborted. A tile the response does not carry (error, cut-off stream)
 * fails its job.
 */
function loadBatch(loader, info, jobs, { frame, format, stats }) {
  const id = loader.nextId++;
  const controller = { abort: () => loader.worker.postMessage({ type: 'abort', id }) };
  // Jobs by tile: the navigator shows this tile source too, so two jobs may want one tile.
  const byKey = new Map();
  const batch = { controller, live: jobs.length };
  const tiles = [];
  for (const job of jobs) {
    const t = { level: vtexLevel(info, job.tile.level), x: job.tile.x, y: job.tile.y };
    const key = tileKey(t.level, t.x, t.y);
    if (byKey.has(key)) byKey.get(key).push(job);
    else {
      byKey.set(key, [job]);
      tiles.push(t);
    }
  }
  const url = batchUrl(info, tiles, frame, format);
  for (const job of jobs) {
    job.userData.batch = batch;
    job.userData.batchUrl = url; // for bench/viewer/trace.mjs
  }
  stats.batchStarted();
  // A job is settled once its tile came (or the batch failed): it no longer counts as live.
  const settle = (job) => {
    if (job.userData.settled) return;
    job.userData.settled = true;
    const key = tileKey(vtexLevel(info, job.tile.level), job.tile.x, job.tile.y);
    const left = (byKey.get(key) || []).filter((j) => j !== job);
    if (left.length) byKey.set(key, left);
    else byKey.delete(key);
    if (!job.userData.done) batch.live--;
  };
  const fail = (job, message) => {
    settle(job);
    if (job.userData.done) return;
    stats.failedTile(message);
    job.finish(null, null, message);
  };
  const onTile = (t) => {
    const waiting = byKey.get(tileKey(t.level, t.x, t.y));
    if (!waiting) {
      if (t.bitmap) t.bitmap.close();
      onEnd(`the batch answered tile ${t.level}/${t.x}/${t.y}, which it did not ask for`);
      return;
    }
    // The navigator's job and the viewer's may share one tile: each gets a bitmap of its own
    // (copies of the same pixels, taken before any job could close the first).
    const copies = waiting.slice(1).map(() => (t.bitmap ? createImageBitmap(t.bitmap) : null));
    waiting.forEach((job, i) => deliverTo(job, t, i === 0 ? t.bitmap : copies[i - 1]));
  };
  const deliverTo = (job, t, bitmap) => {
    if (t.error) {
      fail(job, t.error);
      return;
    }
    settle(job);
    const data = job.userData;
    data.arrived = pageTime(t.arrived);
    data.cache = t.cache;
    Promise.resolve(bitmap).then(
      (b) => {
        const image = tileImage(b);
        if (data.done) {
          releaseImage(image);
          return;
        }
        stats.loadedTile(performance.now() - data.t0, t.length, t.cache);
        job.finish(image, null);
      },
      (e) => fail(job, `tile ${t.level}/${t.x}/${t.y}: ${e.message}`),
    );
  };
  const onEnd = (error) => {
    loader.batches.delete(id);
    if (error === 'aborted') return; // every tile left was aborted
    const message = error || 'the tile batch ended without this tile';
    for (const job of [...byKey.values()].flat()) fail(job, `${message} (${job.src})`);
  };
  loader.batches.set(id, { onTile, onEnd });
  loader.worker.postMessage({ type: 'load', id, url, format });
}
