// RGBA rows as an opaque ImageBitmap, in a Worker: the raw tiles of fetch-tiles.js and the
// synthesized tiles of synth-tiles.js take this one path to the screen.

/** The canvas pixels pass through on their way to a bitmap, reused (one per Worker). */
let canvas = null;

/**
 * `data` (width × height RGBA, copied at the call) put into an opaque canvas (`alpha: false`)
 * and taken out as its bitmap. The page's canvas draws an opaque (or premultiplied) bitmap as
 * fast as it can: a bitmap marked unpremultiplied is converted at every draw, and an opaque
 * bitmap is cheaper for the Worker to make than a premultiplied `createImageBitmap`
 * (`bench/viewer/ingest.mjs` compares them). The viewer treats tiles as opaque anyway
 * (viewer/tilesource.js `hasTransparency`); these pixels reach the screen exactly (the browser tests
 * compare them), a pixel with alpha would show over black.
 */
export function opaqueBitmap(data, width, height) {
  canvas = canvas || new OffscreenCanvas(width, height);
  if (canvas.width !== width || canvas.height !== height) {
    canvas.width = width;
    canvas.height = height;
  }
  const pixels = new ImageData(new Uint8ClampedArray(data.buffer, data.byteOffset, data.length), width, height);
  canvas.getContext('2d', { alpha: false }).putImageData(pixels, 0, 0);
  return canvas.transferToImageBitmap();
}
