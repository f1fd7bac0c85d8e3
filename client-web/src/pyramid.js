// The vtex tile pyramid as OpenSeadragon sees it.
//
// vtex counts levels from full resolution: level 0 is W × H, level L is
// ceil(W / 2^L) × ceil(H / 2^L), and the last served level (`levels - 1`) fits in one tile.
// OpenSeadragon counts the other way (its level 0 is the smallest), so OSD level k is vtex
// level `levels - 1 - k`. Every function here is pure so it can be tested in Node.

/** vtex level shown at OpenSeadragon level `osdLevel`. */
export function vtexLevel(info, osdLevel) {
  return info.levels - 1 - osdLevel;
}

/** OpenSeadragon level that shows vtex level `level`. */
export function osdLevel(info, level) {
  return info.levels - 1 - level;
}

/** Size in pixels of vtex level `level`: ceil(W / 2^L) × ceil(H / 2^L). */
export function levelSize(info, level) {
  const d = 2 ** level;
  return { width: Math.max(1, Math.ceil(info.width / d)), height: Math.max(1, Math.ceil(info.height / d)) };
}

/** Tiles across and down at vtex level `level`. */
export function tileCount(info, level) {
  const { width, height } = levelSize(info, level);
  return { x: Math.ceil(width / info.tile_size), y: Math.ceil(height / info.tile_size) };
}

/** Whether tile (level, x, y) exists on the server; nothing outside this is ever requested. */
export function inPyramid(info, level, x, y) {
  if (!Number.isInteger(level) || !Number.isInteger(x) || !Number.isInteger(y)) return false;
  if (level < 0 || level >= info.levels || x < 0 || y < 0) return false;
  const n = tileCount(info, level);
  return x < n.x && y < n.y;
}

/**
 * URL of one tile, or null when (level, x, y) lies outside the pyramid. `frame` is sent only
 * for animated textures (the server normalises it to 0 otherwise, so sending it would only
 * split the browser's cache).
 */
export function tileUrl(info, level, x, y, frame = 0, format = 'png') {
  if (!inPyramid(info, level, x, y)) return null;
  const base = `/api/v1/textures/${encodeURIComponent(info.id)}/tiles/${level}/${x}/${y}.${format}`;
  return info.animated ? `${base}?frame=${frame >>> 0}` : base;
}

/**
 * OpenSeadragon's `minPixelRatio`: the smallest on-screen size of a tile pixel before the next
 * finer level is fetched. Just above one half, so at exactly 1/2^L level L is drawn at 1:1
 * (OSD's default of 0.5 fetches level L-1, four times the tiles, to draw it at half size) and
 * no level is ever drawn magnified by more than 2 %.
 */
export const MIN_PIXEL_RATIO = 0.51;

/** The finest vtex level OpenSeadragon draws at `zoom` screen pixels per level-0 pixel. */
export function drawLevel(info, zoom) {
  if (!(zoom > 0)) return info.levels - 1;
  // OSD: highest level = floor(log2(zoom × 2^(levels-1) / minPixelRatio)), capped at maxLevel.
  const osd = Math.floor(Math.log2((zoom * 2 ** (info.levels - 1)) / MIN_PIXEL_RATIO));
  return vtexLevel(info, Math.min(info.levels - 1, Math.max(0, osd)));
}
