// Clients no one here wrote, reading vtex through the ecosystem's addressing, each through its
// public API only: OpenSeadragon (npm) opening the Deep Zoom and IIIF sources of the 100k demo
// texture, Leaflet (npm) showing its XYZ layer from its TileJSON.
// Run: node --test tests/browser/   (needs target/release/vtex and client-web/dist built)
import test, { after, before } from 'node:test';
import assert from 'node:assert/strict';
import { join } from 'node:path';
import { compareScreenToTexels, launchBrowser, ROOT, startServer } from './lib.mjs';

// OpenSeadragon as the viewer's build ships it; Leaflet from client-web's node_modules.
const OSD = '<script src="/osd/openseadragon.min.js"></script>';
const LEAFLET = '<link rel="stylesheet" href="/leaflet/leaflet.css"><script src="/leaflet/leaflet.js"></script>';

let server;
let browser;
let big;

before(async () => {
  server = await startServer();
  browser = await launchBrowser();
  const { textures } = await (await fetch(`${server.url}/api/v1/textures`)).json();
  big = textures.find((t) => t.width >= 100_000 && t.height >= 100_000);
  assert.ok(big, 'the demo textures include a 100k × 100k one');
});

after(async () => {
  await browser?.close();
  await server?.stop();
});

/** A blank page on the server's origin with `body` (the library's script tags and a 512² `#view`). */
async function blankPage(body) {
  const page = await browser.context.newPage();
  const log = { errors: [], bad: [], requests: [] };
  page.on('pageerror', (e) => log.errors.push(String(e)));
  page.on('console', (m) => m.type() === 'error' && log.errors.push(m.text()));
  page.on('request', (r) => log.requests.push(r.url()));
  page.on('response', (r) => r.status() >= 400 && log.bad.push(`${r.status()} ${r.url()}`));
  const html = `<!doctype html><html><body style="margin:0"><div id="view" style="width:512px;height:512px"></div>${body}</body></html>`;
  await page.route(`${server.url}/interop-test.html`, (route) => route.fulfill({ body: html, contentType: 'text/html' }));
  await page.route(`${server.url}/leaflet/**`, (route) =>
    route.fulfill({ path: join(ROOT, 'client-web', 'node_modules', 'leaflet', 'dist', new URL(route.request().url()).pathname.slice(9)) }),
  );
  await page.goto(`${server.url}/interop-test.html`);
  return { page, log };
}

/** Opens `source` in OpenSeadragon, shows image pixel (x, y) at the centre magnified `scale`×. */
async function show(page, source, x, y, scale) {
  await page.evaluate(
    ([source, x, y, scale]) =>
      new Promise((resolve, reject) => {
        const viewer = OpenSeadragon({
          element: document.getElementById('view'),
          tileSources: source,
          drawer: 'canvas',
          imageSmoothingEnabled: false,
          animationTime: 0,
          blendTime: 0,
          showNavigationControl: false,
          maxZoomPixelRatio: 16,
        });
        window.osd = viewer;
        window.screenOf = (x, y) => {
          const item = viewer.world.getItemAt(0);
          const a = item.imageToViewerElementCoordinates(new OpenSeadragon.Point(x, y));
          const b = item.imageToViewerElementCoordinates(new OpenSeadragon.Point(x + 100, y + 100));
          return { ax: a.x, ay: a.y, sx: (b.x - a.x) / 100, sy: (b.y - a.y) / 100 };
        };
        viewer.addHandler('open-failed', (e) => reject(new Error(e.message)));
        viewer.addHandler('open', () => {
          const item = viewer.world.getItemAt(0);
          // Again once open: sizing the canvas resets its context's smoothing.
          viewer.drawer.setImageSmoothingEnabled(false);
          viewer.viewport.zoomTo(item.imageToViewportZoom(scale), null, true);
          viewer.viewport.panTo(item.imageToViewportCoordinates(x, y), true);
          resolve();
        });
      }),
    [source, x, y, scale],
  );
  await page.waitForFunction(
    () => {
      const item = window.osd.world.getItemAt(0);
      return item && item.getFullyLoaded() && !window.osd.world.needsDraw();
    },
    null,
    { timeout: 60_000, polling: 50 },
  );
}

/**
 * Every screen pixel of a `size`² box shows the level-0 texel under its centre, exactly as the
 * server's tile has it. The box is centred on image point (x, y), or starts there when
 * `corner`; the page's `screenOf(x, y)` says where an image point is on screen and at what
 * scale. Returns the number of pixels compared and the tiles they came from.
 */
async function checkAgainstTiles(page, info, x, y, { size = 200, corner = false } = {}) {
  const at = await page.evaluate(([x, y]) => window.screenOf(x, y), [x, y]);
  const half = corner ? 0 : size / 2;
  const clip = { x: Math.round(at.ax - half), y: Math.round(at.ay - half), width: size, height: size };
  return compareScreenToTexels(page, server.url, info, x, y, at, clip);
}

// A spot deep inside the texture: the corner of four level-0 tiles.
const SPOT = { x: 73_216, y: 41_472 };

test("OpenSeadragon opens the 100k texture's Deep Zoom source and shows the server's pixels", async () => {
  const { page, log } = await blankPage(OSD);
  // Overlap 1: with none, OpenSeadragon draws every tile a pixel larger to hide seams.
  await show(page, `${server.url}/dzi/${big.id}.dzi?overlap=1`, SPOT.x, SPOT.y, 4);
  const { compared, tiles } = await checkAgainstTiles(page, big, SPOT.x, SPOT.y);
  assert.ok(compared > 30_000 && tiles === 4, `compared ${compared} pixels of ${tiles} tiles`);
  const finest = log.requests.filter((u) => /^\/dzi\/[0-9a-f]{64}_files\/17\/\d+_\d+\.png$/.test(new URL(u).pathname));
  assert.ok(finest.length >= 4, `full-resolution Deep Zoom tiles fetched: ${log.requests.slice(-5)}`);
  assert.deepEqual(log.errors, []);
  assert.deepEqual(log.bad, []);
  await page.close();
});

test("OpenSeadragon opens the 100k texture's IIIF source and shows the server's pixels", async () => {
  const { page, log } = await blankPage(OSD);
  // At 1:1. IIIF tiles have no overlap, so OpenSeadragon stretches each by one pixel (its seam
  // hiding) and repeats one row and column in its second half; the first half is exact.
  await show(page, `${server.url}/iiif/3/${big.id}/info.json`, SPOT.x, SPOT.y, 1);
  const { compared } = await checkAgainstTiles(page, big, SPOT.x, SPOT.y, { size: 120, corner: true });
  assert.equal(compared, 120 * 120);
  const finest = log.requests.filter((u) =>
    /^\/iiif\/3\/[0-9a-f]{64}\/\d+,\d+,256,256\/256,256\/0\/default\.png$/.test(new URL(u).pathname),
  );
  assert.ok(finest.length >= 4, `full-resolution IIIF tiles fetched: ${log.requests.slice(-5)}`);
  assert.deepEqual(log.errors, []);
  assert.deepEqual(log.bad, []);
  await page.close();
});

test("Leaflet shows the 100k texture's XYZ layer from its TileJSON, the server's pixels at 1:1", async () => {
  const tj = await (await fetch(`${server.url}/api/v1/textures/${big.id}/tilejson.json`)).json();
  const { page, log } = await blankPage(LEAFLET);
  await page.evaluate(
    ([tj, x, y]) =>
      new Promise((resolve) => {
        const map = L.map('view', { zoomControl: false, attributionControl: false, fadeAnimation: false, zoomAnimation: false });
        const [west, south, east, north] = tj.bounds;
        const layer = L.tileLayer(tj.tiles[0], {
          minZoom: tj.minzoom,
          maxZoom: tj.maxzoom,
          tileSize: tj.tile_size,
          noWrap: true,
          bounds: L.latLngBounds([south, west], [north, east]),
        });
        layer.once('load', resolve);
        layer.addTo(map);
        // At the highest zoom a map pixel is a texel: image point (x, y) is map pixel (x, y).
        map.setView(map.unproject([x, y], tj.maxzoom), tj.maxzoom, { animate: false });
        window.screenOf = (x, y) => {
          const p = map.latLngToContainerPoint(map.unproject([x, y], tj.maxzoom));
          return { ax: p.x, ay: p.y, sx: 1, sy: 1 };
        };
      }),
    [tj, SPOT.x, SPOT.y],
  );
  const { compared, tiles } = await checkAgainstTiles(page, big, SPOT.x, SPOT.y);
  assert.ok(compared === 200 * 200 && tiles === 4, `compared ${compared} pixels of ${tiles} tiles`);
  const xyz = log.requests.filter((u) => new RegExp(`^/api/v1/textures/${big.id}/xyz/${tj.maxzoom}/\\d+/\\d+\\.png$`).test(new URL(u).pathname));
  assert.ok(xyz.length >= 4, `XYZ tiles fetched: ${log.requests.slice(-5)}`);
  assert.deepEqual(log.errors, []);
  assert.deepEqual(log.bad, []);
  await page.close();
});
