// Incremental frames for OpenSeadragon's canvas drawer while a view's tiles arrive.
//
// OpenSeadragon redraws the whole view in every frame in which a tile arrived: it clears the
// canvas and draws every tile again, coarsest level first. On the software canvas of the test
// machine that is ~4 ms of rastering on the page's main thread for a zoomed-out view of ~50
// tiles, in each of the ~6 frames a view takes to arrive — main-thread time the same thread
// needs to take in the tiles' bytes (BENCHMARKS.md "Viewer", `bench.mjs --profile`). When the
// view has not moved since the last frame and the tiles that arrived are at least as fine as
// every tile already drawn, drawing just those on top of the canvas gives the frame a full
// redraw would (tiles are opaque, and a full redraw draws them after the coarser ones too);
// otherwise the frame is a full redraw, as before.

/**
 * The tiles to draw on top of a canvas showing `prev` (in the order they were drawn) so that it
 * shows `next`, the tiles of the same view now: those of `next` not in `prev`, in `next`'s
 * order — or null when only a full redraw will do: a tile of `prev` is no longer drawn (it
 * would have to be painted over), or a new tile is coarser than one already drawn (it would
 * cover it). Tiles are compared by identity and carry their OpenSeadragon `level` (higher is
 * finer).
 */
export function tilesToAdd(prev, next) {
  const now = new Set(next);
  if (prev.some((t) => !now.has(t))) return null;
  const had = new Set(prev);
  let finest = -Infinity;
  for (const t of prev) finest = Math.max(finest, t.level);
  const add = next.filter((t) => !had.has(t));
  return add.every((t) => t.level >= finest) ? add : null;
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
 * frame as a full redraw (`tilesToAdd`, `viewKey`). Draws a new tile with the drawer's own
 * tile drawing (`_drawTile`, OpenSeadragon 5's canvas drawer) and raises `tile-drawn` for it, as
 * a full redraw does for every tile. Does nothing for a drawer without `_drawTile`. Returns
 * the counts of full and incremental frames, live.
 */
export function drawIncrementally(viewer) {
  const drawer = viewer.drawer;
  // Frames drawn in full and frames that only added tiles (for tests and the curious).
  const counts = { full: 0, incremental: 0 };
  if (!drawer || typeof drawer._drawTile !== 'function') return counts;
  const fullDraw = drawer.draw.bind(drawer);
  let last = null; // { key, item, tiles }: what the canvas shows
  drawer.draw = (items) => {
    const key = viewKey(viewer, items);
    const item = key === null ? null : items.find((i) => i.opacity !== 0);
    if (last && key !== null && key === last.key && item === last.item) {
      const next = item.getTilesToDraw().map((info) => info.tile);
      const add = tilesToAdd(last.tiles, next);
      if (add) {
        for (const tile of add) {
          drawer._drawTile(tile, item, false, 1, undefined, false, item.source);
          viewer.raiseEvent('tile-drawn', { tiledImage: item, tile });
        }
        last.tiles = next;
        counts.incremental++;
        return;
      }
    }
    fullDraw(items);
    counts.full++;
    // getTilesToDraw() marks tiles as drawn and refreshes their coverage; the full draw just did
    // that, so its list (`_lastDrawn`) is read rather than computed again.
    last = key === null ? null : { key, item, tiles: (item._lastDrawn || []).map((info) => info.tile) };
  };
  // A forced redraw (OpenSeadragon's own, e.g. after the smoothing changed, or the page's) is a
  // full one.
  const forceRedraw = viewer.forceRedraw.bind(viewer);
  viewer.forceRedraw = () => {
    last = null;
    return forceRedraw();
  };
  return counts;
}
