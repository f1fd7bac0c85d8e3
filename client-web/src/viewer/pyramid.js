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
 * The vtex tile (level, x, y) that OpenSeadragon's tile `tile` ({ level, x, y } in its numbering)
 * shows. Past the edge of a texture that wraps (a torus, `info.wraps`), OpenSeadragon numbers
 * the repeated copies' tiles on (x + k × columns, y + j × rows); they show the tile at the
 * coordinates taken modulo the level's grid. Elsewhere the coordinates are left as they are.
 */
export function sourceTile(info, tile) {
  const level = vtexLevel(info, tile.level);
  if (!info.wraps) return { level, x: tile.x, y: tile.y };
  const n = tileCount(info, level);
  return { level, x: modulo(tile.x, n.x), y: modulo(tile.y, n.y) };
}

/** `a` modulo `n`, in [0, n) also for a negative `a`. */
export const modulo = (a, n) => ((a % n) + n) % n;

/**
 * URL of one tile relative to the viewer's page, or null when (level, x, y) lies outside the
 * pyramid. `frame` is sent only for animated textures (the server normalises it to 0 otherwise,
 * so sending it would only split the browser's cache).
 */
export function tileUrl(info, level, x, y, frame = 0, format = 'png') {
  if (!inPyramid(info, level, x, y)) return null;
  const base = `api/v1/textures/${encodeURIComponent(info.id)}/tiles/${level}/${x}/${y}.${format}`;
  return info.animated ? `${base}?frame=${frame >>> 0}` : base;
}

/**
 * URL of metatile (level, x, y) relative to the viewer's page: the aligned block of
 * `info.metatile` × `info.metatile` tiles from tile (x × metatile, y × metatile), one cacheable
 * response of the tiles' frames (shared/batch.js FrameReader).
 */
export function metatileUrl(info, level, x, y, frame = 0, format = 'png') {
  const base = `api/v1/textures/${encodeURIComponent(info.id)}/metatiles/${level}/${x}/${y}.${format}`;
  return info.animated ? `${base}?frame=${frame >>> 0}` : base;
}

/**
 * The metatiles holding `tiles` ({ level, x, y } inside the pyramid), each as { level, x, y,
 * tiles } with the given tiles it holds, coarsest level first: a view's coarse preview is one
 * or two cheap metatiles, asked for before the finest level's.
 */
export function metatilesOf(info, tiles) {
  const side = info.metatile;
  const blocks = new Map();
  for (const t of tiles) {
    const b = { level: t.level, x: Math.floor(t.x / side), y: Math.floor(t.y / side) };
    const key = `${b.level}/${b.x}/${b.y}`;
    if (!blocks.has(key)) blocks.set(key, { ...b, tiles: [] });
    blocks.get(key).tiles.push(t);
  }
  return [...blocks.values()].sort((a, b) => b.level - a.level);
}

/**
 * How fine a level the viewer draws, as OpenSeadragon's `minPixelRatio`: the smallest on-screen
 * size of a tile pixel before the next finer level is fetched.
 * - `map`: the level nearest the screen's resolution, as a GPU picks a mip level and as map
 *   viewers pick a zoom level: tile pixels show at 0.71–1.41 screen pixels, so a view fetches
 *   0.5–2 × its own pixels (1.1 × on average over zooms).
 * - `sharp`: never magnified (by more than 2 %): tile pixels show at 0.51–1.02 screen pixels,
 *   0.96–3.8 × the view's pixels (2.1 × on average), twice the tiles of `map`. Just above
 *   OpenSeadragon's default of one half, so at exactly 1/2^L level L is drawn at 1:1.
 * Both draw level L at 1:1 at a zoom of exactly 1/2^L.
 */
export const DETAIL = { map: Math.SQRT1_2, sharp: 0.51 };
export const DEFAULT_DETAIL = 'map';

/**
 * The finest vtex level OpenSeadragon draws at `zoom` screen pixels per level-0 pixel, with
 * `minPixelRatio` (a DETAIL value).
 */
export function drawLevel(info, zoom, minPixelRatio = DETAIL[DEFAULT_DETAIL]) {
  if (!(zoom > 0)) return info.levels - 1;
  // OSD: highest level = floor(log2(zoom × 2^(levels-1) / minPixelRatio)), capped at maxLevel.
  const osd = Math.floor(Math.log2((zoom * 2 ** (info.levels - 1)) / minPixelRatio));
  return vtexLevel(info, Math.min(info.levels - 1, Math.max(0, osd)));
}
