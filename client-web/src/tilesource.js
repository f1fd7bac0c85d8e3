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
          const { bitmap, bytes } = format === 'rgba' ? await rgbaBitmap(response) : await imageBitmap(response);
          stats.loadedTile(performance.now() - t0, bytes, cache);
          if (data.done) bitmap.close();
          else finish(bitmap, null);
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

    createTileCache(cache, bitmap) {
      cache._data = bitmap;
    },

    destroyTileCache(cache) {
      if (cache._data && cache._data.close) cache._data.close();
      cache._data = null;
      cache._renderedContext = null;
    },

    getTileCacheData(cache) {
      return cache._data;
    },

    getTileCacheDataAsImage(cache) {
      return cache._data;
    },

    // The canvas drawer draws from a 2D context; copy the bitmap once, then free it (the html
    // drawer, the only user of getTileCacheDataAsImage, is not used by this viewer).
    getTileCacheDataAsContext2D(cache) {
      if (!cache._renderedContext) {
        const bitmap = cache._data;
        const canvas = document.createElement('canvas');
        canvas.width = bitmap.width;
        canvas.height = bitmap.height;
        const ctx = canvas.getContext('2d');
        ctx.drawImage(bitmap, 0, 0);
        bitmap.close();
        cache._data = null;
        cache._renderedContext = ctx;
      }
      return cache._renderedContext;
    },
  });
}

/** An encoded tile (PNG, WebP, JPEG), decoded off the main thread. */
async function imageBitmap(response) {
  const blob = await response.blob();
  return { bitmap: await createImageBitmap(blob), bytes: blob.size };
}

/** A raw RGBA tile: no decoding at all, its size from X-Vtex-Width/Height. */
async function rgbaBitmap(response) {
  const w = Number(response.headers.get('X-Vtex-Width'));
  const h = Number(response.headers.get('X-Vtex-Height'));
  const buffer = await response.arrayBuffer();
  if (!(Number.isInteger(w) && Number.isInteger(h) && w > 0 && h > 0) || buffer.byteLength !== w * h * 4) {
    throw new Error(`raw tile of ${buffer.byteLength} bytes does not match ${w} × ${h} RGBA`);
  }
  const pixels = new ImageData(new Uint8ClampedArray(buffer), w, h);
  return { bitmap: await createImageBitmap(pixels), bytes: buffer.byteLength };
}
