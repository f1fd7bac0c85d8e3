// Incremental frames for OpenSeadragon's canvas drawer while a view's tiles arrive.
//
// OpenSeadragon redraws the whole view in every frame in which a tile arrived: it clears the
// canvas and draws every tile again, coarsest level first. On the software canvas of the test
// machine that is ~4 ms of rastering on the page's main thread for a zoomed-out view of ~50
// tiles, in each of the ~6 frames a view takes to arrive — main-thread time the same thread
// needs to take in the tiles' bytes (BENCHMARKS.md "Viewer", `bench.mjs --profile`). When the
// view has not moved since the last frame and the tiles that arrived are at least as fine as
// every tile already drawn, drawing just those on top of the canvas gives the frame a full
// redraw would (tiles are opaque, and a full redraw draws them after the coarser ones too) —
// clipped where a full redraw would draw an old neighbour over one; otherwise the frame is a
// full redraw, as before.
//
// In either kind of frame, tiles that opaque tiles drawn after them in the same frame paint over
// entirely are not drawn at all (occlusion.js), and the frame in which a finer level completes
// the view (OpenSeadragon then stops listing the coarser tiles under it) only adds its new
// tiles: the frame's pixels stay those of OpenSeadragon's full redraw, byte for byte
// (tests/browser/viewer.test.mjs), with fewer pixels rastered (`bench.mjs`, canvas table).

import { addClips, hiddenTiles, rasterModel, tileBoxes } from './occlusion.js';

/**
 * The tiles to draw on top of a canvas showing `prev` (in the order they were drawn) so that it
 * shows `next`, the tiles of the same view now: those of `next` not in `prev`, in `next`'s
 * order — or null when only a full redraw will do:
 * - a new tile is coarser than one already drawn (it would cover it);
 * - `clip` (given the new tiles: whether they can be drawn so that old tiles `next` lists
 *   after them stay on top, occlusion.js `addClips`) says no;
 * - a tile of `prev` is no longer drawn (it would have to be painted over) — unless `hidden`
 *   (given a drawing order, the set of its tiles that tiles drawn later hide, occlusion.js)
 *   finds every such tile hidden by the time the new tiles are drawn: then the canvas will not
 *   show it either. That is the frame in which a finer level completes the view and
 *   OpenSeadragon stops listing the coarser tiles under it.
 * Tiles are compared by identity and carry their OpenSeadragon `level` (higher is finer).
 */
export function tilesToAdd(prev, next, { clip = null, hidden = null } = {}) {
  const had = new Set(prev);
  let finest = -Infinity;
  for (const t of prev) finest = Math.max(finest, t.level);
  const add = next.filter((t) => !had.has(t));
  if (!add.every((t) => t.level >= finest)) return null;
  if (clip && !clip(add)) return null;
  const now = new Set(next);
  const gone = prev.filter((t) => !now.has(t));
  if (gone.length === 0) return add;
  if (!hidden) return null;
  const h = hidden([...prev, ...add]);
  return gone.every((t) => h.has(t)) ? add : null;
}

/**
 * What a frame draws, as a string, when incremental frames are possible at all: a view without
 * rotation or flip, and one visible tiled image drawn straight onto the canvas (opaque, no
 * clip, no blending, not through OpenSeadragon's sketch canvas). Null otherwise. Two frames with
 * the same key show the same view of the same image.
 */
export function viewKey(viewer, items) {
  const vp = viewer.viewport;
  if (vp.getRotation(true) % 360 !== 0 || vp.getFlip()) return null;
  const visible = items.filter((item) => item.opacity !== 0);
  if (visible.length !== 1) return null;
  const item = visible[0];
  const plain =
    item.opacity === 1 &&
    (!item.compositeOperation || item.compositeOperation === 'source-over') &&
    !item._clip &&
    !item._croppingPolygons &&
    !item.placeholderFillStyle &&
    !item.debugMode &&
    // A tile fading in is drawn at partial opacity in several frames: only blendTime 0 (main.js).
    !(item.blendTime > 0) &&
    !item.alwaysBlend &&
    item.getRotation(true) % 360 === 0 &&
    // Above this zoom OpenSeadragon composes the tiles on its sketch canvas first.
    !(item.viewportToImageZoom(vp.getZoom(true)) > item.smoothTileEdgesMinZoom);
  if (!plain) return null;
  const b = vp.getBoundsNoRotate(true);
  const size = vp.getContainerSize();
  const smoothing = viewer.drawer._imageSmoothingEnabled;
  return [b.x, b.y, b.width, b.height, size.x, size.y, smoothing, items.indexOf(item), items.length].join(' ');
}

/**
 * Makes `viewer`'s canvas drawer draw only the newly arrived tiles when that gives the same
 * frame as a full redraw (`tilesToAdd`, `viewKey`), and in every such plain frame leave out
 * the tiles that tiles drawn later in it hide (`hiddenTiles`). Draws a new tile with the
 * drawer's own tile drawing (`_drawTile`, OpenSeadragon 5's canvas drawer) and raises
 * `tile-drawn` for it, as a full redraw does for every tile it draws. Does nothing for a
 * drawer without `_drawTile`. Returns the frame counts, live: full and incremental frames,
 * tiles drawn and left out, canvas pixels they touch (drawn and left out; in plain frames),
 * new tiles drawn clipped under old ones (`addClips`); `prune` switches the hiding (tests and
 * the bench compare frames with and without it) and `centres` tells the raster model.
 */
export function drawIncrementally(viewer) {
  const drawer = viewer.drawer;
  const frames = { full: 0, incremental: 0, tiles: 0, hidden: 0, pixels: 0, hiddenPixels: 0, clipped: 0, prune: true, centres: false };
  if (!drawer || typeof drawer._drawTile !== 'function') return frames;
  frames.centres = rasterModel();
  const fullDraw = drawer.draw.bind(drawer);
  /** The canvas, as occlusion.js measures it. */
  const canvasOf = () => {
    const canvas = drawer.canvas || {};
    const osd = globalThis.OpenSeadragon;
    return { width: canvas.width ?? Infinity, height: canvas.height ?? Infinity, ratio: (osd && osd.pixelDensityRatio) || 1, centres: frames.centres };
  };
  /** What of `tiles` (drawn in that order) to leave out, counted: nothing unless pruning. */
  const plan = (tiles, clips = null) => {
    const h = hiddenTiles(tiles, canvasOf(), clips);
    const p = frames.prune ? h : { hidden: new Set(), trims: new Map(), hiddenArea: 0, trimmedArea: 0 };
    frames.tiles += tiles.length - p.hidden.size;
    frames.hidden += p.hidden.size;
    frames.pixels += h.area - p.hiddenArea - p.trimmedArea;
    frames.hiddenPixels += p.hiddenArea + p.trimmedArea;
    return p;
  };
  /** Counts tiles a frame did not draw again because they are hidden (full frames draw them). */
  const countHidden = (tiles) => {
    const canvas = canvasOf();
    for (const t of tiles) {
      const b = tileBoxes(t, canvas);
      if (b) frames.hiddenPixels += Math.max(0, b.touch[2] - b.touch[0]) * Math.max(0, b.touch[3] - b.touch[1]);
    }
    frames.hidden += tiles.length;
  };
  let last = null; // { key, item, tiles }: what the canvas shows (as if every tile were drawn)
  drawer.draw = (items) => {
    const view = viewKey(viewer, items);
    const key = view === null ? null : `${view} ${frames.prune}`;
    const item = key === null ? null : items.find((i) => i.opacity !== 0);
    if (last && key !== null && key === last.key && item === last.item) {
      const next = item.getTilesToDraw().map((info) => info.tile);
      const canvas = canvasOf();
      let clips = null;
      const add = tilesToAdd(last.tiles, next, {
        clip: (tiles) => (clips = addClips(last.tiles, tiles, next, canvas)) !== null,
        hidden: frames.prune ? (tiles) => hiddenTiles(tiles, canvas, clips).hidden : null,
      });
      if (add) {
        const now = new Set(next);
        countHidden(last.tiles.filter((t) => !now.has(t)));
        const { hidden, trims } = plan(add, clips);
        for (const tile of add) {
          if (hidden.has(tile)) continue;
          const clip = trims.get(tile) || clips.get(tile);
          const drawTile = () => drawer._drawTile(tile, item, false, 1, undefined, false, item.source);
          if (clip && clip.length === 0) continue; // wholly under old tiles listed after it
          if (clip) {
            frames.clipped++;
            drawClipped(drawer.context, clip, drawTile);
          } else {
            drawTile();
          }
          viewer.raiseEvent('tile-drawn', { tiledImage: item, tile });
        }
        last.tiles = next;
        frames.incremental++;
        return;
      }
    }
    if (item) drawPruned(drawer, item, plan, () => fullDraw(items));
    else fullDraw(items);
    frames.full++;
    // getTilesToDraw() marks tiles as drawn and refreshes their coverage; the full draw just did
    // that, so its list (`_lastDrawn`, every tile, hidden ones too) is read rather than computed again.
    last = key === null ? null : { key, item, tiles: (item._lastDrawn || []).map((info) => info.tile) };
  };
  // A forced redraw (OpenSeadragon's own, e.g. after the smoothing changed, or the page's) is a
  // full one.
  const forceRedraw = viewer.forceRedraw.bind(viewer);
  viewer.forceRedraw = () => {
    last = null;
    return forceRedraw();
  };
  return frames;
}

/** Runs `draw` with `context` clipped to `boxes` (device px, whole pixels: an exact clip). */
function drawClipped(context, boxes, draw) {
  context.save();
  try {
    context.beginPath();
    for (const [x0, y0, x1, y1] of boxes) context.rect(x0, y0, x1 - x0, y1 - y0);
    context.clip();
    draw();
  } finally {
    context.restore();
  }
}

/**
 * Runs `draw` (a full frame of OpenSeadragon's drawer) with `item` handing the drawer its tiles
 * to draw minus those `plan` hides, and the drawer drawing those `plan` trims clipped: the
 * drawer asks the tiled image for its tiles once per frame (`getTilesToDraw`, which also
 * records them all as the frame's tiles, `_lastDrawn`) and draws each with `_drawTile`.
 */
function drawPruned(drawer, item, plan, draw) {
  let trims = new Map();
  const restore = [shadow(item, 'getTilesToDraw'), shadow(drawer, '_drawTile')];
  const tilesToDraw = item.getTilesToDraw;
  item.getTilesToDraw = function () {
    const infos = tilesToDraw.call(this);
    const p = plan(infos.map((info) => info.tile));
    trims = p.trims;
    return p.hidden.size ? infos.filter((info) => !p.hidden.has(info.tile)) : infos;
  };
  const drawTile = drawer._drawTile;
  drawer._drawTile = function (tile, ...rest) {
    const clip = trims.get(tile);
    if (!clip) return drawTile.call(this, tile, ...rest);
    drawClipped(this.context, clip, () => drawTile.call(this, tile, ...rest));
  };
  try {
    draw();
  } finally {
    for (const r of restore) r();
  }
}

/** Undoes a later assignment to `object[name]`: back to its own property or its prototype's. */
function shadow(object, name) {
  const own = Object.getOwnPropertyDescriptor(object, name);
  return () => {
    if (own) Object.defineProperty(object, name, own);
    else delete object[name];
  };
}
