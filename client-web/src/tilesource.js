// An OpenSeadragon tile source over the vtex tile API, loading tiles with fetch so that the
// viewer sees what the server says about each one (X-Vtex-Cache) and how long it took.
// Formats: png / webp (lossless), jpg (lossy, smallest) and rgba (raw: no decoding, the
// fastest on a fast link).

import { inPyramid, tileUrl, vtexLevel } from './pyramid.js';

/**
 * Makes the tile source for texture `info` (the server's info JSON) at animation `frame`.
 * `stats` is a TileStats that every download reports to.
 */
export function createTileSource(OSD, info, { frame = 0, format = 'png', stats }) {
  const maxLevel = info.levels - 1;
  return new OSD.TileSource({
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

    downloadTileStart(job) {
      const data = job.userData;
      const controller = new AbortController();
      data.controller = controller;
      data.done = false;
      const finish = (result, error) => {
        if (data.done) return;
        data.done = true;
        job.finish(result, null, error);
      };
      const t0 = performance.now();
      stats.started();
      fetch(job.src, { signal: controller.signal, credentials: 'same-origin' })
        .then(async (response) => {
          if (!response.ok) {
            let detail = '';
            try {
              detail = (await response.json()).error || '';
            } catch {
              // body was not the JSON error the contract promises; the status says enough
            }
            throw new Error(`HTTP ${response.status} for ${job.src}${detail ? `: ${detail}` : ''}`);
          }
          const cache = response.headers.get('X-Vtex-Cache');
          const { context, bytes } = format === 'rgba' ? await rgbaTile(response) : await encodedTile(response);
          stats.loadedTile(performance.now() - t0, bytes, cache);
          if (data.done) releaseContext(context);
          else finish(context, null);
        })
        .catch((error) => {
          if (error && error.name === 'AbortError') {
            stats.abortedTile();
            return;
          }
          stats.failedTile(String(error && error.message ? error.message : error));
          finish(null, String(error));
        });
    },

    downloadTileAbort(job) {
      job.userData.done = true;
      if (job.userData.controller) job.userData.controller.abort();
    },

    // A tile arrives as the 2D context the canvas drawer draws from (see tileContext below), so
    // nothing is converted while a frame is drawn.
    createTileCache(cache, context) {
      cache._data = context;
    },

    destroyTileCache(cache) {
      if (cache._data) releaseContext(cache._data);
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
}

/**
 * A canvas of w × h and its 2D context: a tile's pixels, ready for the drawer. Filled when the
 * tile arrives (in the fetch's task, between frames) rather than on first draw (inside a frame).
 */
function tileContext(w, h) {
  const canvas = document.createElement('canvas');
  canvas.width = w;
  canvas.height = h;
  return canvas.getContext('2d');
}

/** Frees a tile's pixels now rather than at the next garbage collection. */
function releaseContext(context) {
  context.canvas.width = 0;
  context.canvas.height = 0;
}

/** An encoded tile (PNG, WebP, JPEG), decoded off the main thread, then copied into a canvas. */
async function encodedTile(response) {
  const blob = await response.blob();
  const bitmap = await createImageBitmap(blob);
  const context = tileContext(bitmap.width, bitmap.height);
  context.drawImage(bitmap, 0, 0);
  bitmap.close();
  return { context, bytes: blob.size };
}

/**
 * A raw RGBA tile: no decoding at all, its size from X-Vtex-Width/Height; the bytes go straight
 * into the tile's canvas (one copy, no ImageBitmap round trip through another thread).
 */
async function rgbaTile(response) {
  const w = Number(response.headers.get('X-Vtex-Width'));
  const h = Number(response.headers.get('X-Vtex-Height'));
  const buffer = await response.arrayBuffer();
  if (!(Number.isInteger(w) && Number.isInteger(h) && w > 0 && h > 0) || buffer.byteLength !== w * h * 4) {
    throw new Error(`raw tile of ${buffer.byteLength} bytes does not match ${w} × ${h} RGBA`);
  }
  const context = tileContext(w, h);
  context.putImageData(new ImageData(new Uint8ClampedArray(buffer), w, h), 0, 0);
  return { context, bytes: buffer.byteLength };
}
