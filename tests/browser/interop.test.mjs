// Clients no one here wrote, reading vtex through the ecosystem's addressing, each through its
// public API only: OpenSeadragon (npm) opening the Deep Zoom and IIIF sources of the 100k demo
// texture; MapLibre GL JS, Leaflet and OpenLayers (npm) showing its XYZ layer, compared with
// the server's tiles inside the texture and along its right and bottom edges.
// Run: node --test tests/browser/   (needs target/release/vtex and client-web/dist built)
import test, { after, before } from 'node:test';
import assert from 'node:assert/strict';
import { join } from 'node:path';
import { compareScreenToTexels, launchBrowser, ROOT, startServer } from './lib.mjs';

// OpenSeadragon as the viewer's build ships it; the map libraries from client-web's
// node_modules as published (MapLibre as its ES module, which loads its worker module next to
// it; OpenLayers as its full build, the global `ol`).
const OSD = '<script src="/osd/openseadragon.min.js"></script>';
const NPM = '/node_modules';
const LEAFLET = `<link rel="stylesheet" href="${NPM}/leaflet/dist/leaflet.css"><script src="${NPM}/leaflet/dist/leaflet.js"></script>`;
const MAPLIBRE = `<link rel="stylesheet" href="${NPM}/maplibre-gl/dist/maplibre-gl.css"><script type="module">
  import * as maplibregl from '${NPM}/maplibre-gl/dist/maplibre-gl.mjs';
  window.maplibregl = maplibregl;
</script>`;
const OL = `<link rel="stylesheet" href="${NPM}/ol/ol.css"><script src="${NPM}/ol/dist/ol.js"></script>`;
// The view's own colour, which shows wherever a layer is transparent.
const BACKGROUND = [255, 0, 255];

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
  const [r, g, b] = BACKGROUND;
  const view = `<div id="view" style="width:512px;height:512px;background:rgb(${r},${g},${b})"></div>`;
  const html = `<!doctype html><html><body style="margin:0">${view}${body}</body></html>`;
  await page.route(`${server.url}/interop-test.html`, (route) => route.fulfill({ body: html, contentType: 'text/html' }));
  await page.route(`${server.url}${NPM}/**`, (route) =>
    route.fulfill({ path: join(ROOT, 'client-web', new URL(route.request().url()).pathname) }),
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
 * Every screen pixel of a `size`² box shows the texel of `level` under its centre, exactly as
 * the server's tile has it, and `beyond` past the level's edge. The box is centred on level
 * point (x, y), or starts there when `corner`; the page's `screenOf(x, y)` says where a level
 * point is on screen and at what scale. Returns what compareScreenToTexels does.
 */
async function checkAgainstTiles(page, info, x, y, { size = 200, corner = false, level = 0, beyond } = {}) {
  const at = await page.evaluate(([x, y]) => window.screenOf(x, y), [x, y]);
  const half = corner ? 0 : size / 2;
  const clip = { x: Math.round(at.ax - half), y: Math.round(at.ay - half), width: size, height: size };
  return compareScreenToTexels(page, server.url, info, x, y, at, clip, { level, beyond });
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

/**
 * The spots a map client is checked at, in texels of `level`: SPOT inside the texture, and the
 * right and bottom edges level with it, where the centred box is half texture, half beyond it.
 */
function spots(level) {
  const s = 2 ** level;
  const [w, h] = [Math.ceil(big.width / s), Math.ceil(big.height / s)];
  const [x, y] = [SPOT.x / s, SPOT.y / s];
  return [
    ['inside', x, y],
    ['right edge', w, y],
    ['bottom edge', x, h],
  ];
}

// Full resolution and a quarter of it, each at one texel a screen pixel.
const LEVELS = [0, 2];

/**
 * At every level of LEVELS and every spot, the page's `goTo(level, x, y)` centres level point
 * (x, y) at one texel a screen pixel and resolves once drawn; the screen then shows the
 * server's texels of that level exactly, and the view's colour beyond the texture.
 */
async function showsTheServersPixels(page, client) {
  for (const level of LEVELS) {
    for (const [where, x, y] of spots(level)) {
      await page.evaluate(([level, x, y]) => window.goTo(level, x, y), [level, x, y]);
      const got = await checkAgainstTiles(page, big, x, y, { level, beyond: BACKGROUND });
      const inside = where === 'inside' ? 200 * 200 : 200 * 100;
      assert.deepEqual([got.compared, got.beyond], [inside, 200 * 200 - inside], `${client}, level ${level}, ${where}`);
    }
  }
}

/** The XYZ zooms of the tiles `requests` fetched from the 100k texture. */
function xyzZooms(requests) {
  const zooms = requests.map((u) => new URL(u).pathname.match(new RegExp(`^/api/v1/textures/${big.id}/xyz/(\\d+)/\\d+/\\d+\\.png$`))?.[1]);
  return [...new Set(zooms.filter(Boolean).map(Number))].sort((a, b) => a - b);
}

// The zooms whose levels LEVELS are (zoom z is level levels − 1 − z).
const ZOOMS = () => LEVELS.map((l) => big.levels - 1 - l).sort((a, b) => a - b);

test("MapLibre GL JS shows the 100k texture from its TileJSON URL: the server's pixels, edges included", async () => {
  const { page, log } = await blankPage(MAPLIBRE);
  await page.waitForFunction(() => window.maplibregl);
  await page.evaluate(
    ([url, ts, maxzoom]) =>
      new Promise((resolve, reject) => {
        const { Map, MercatorCoordinate } = window.maplibregl;
        const map = new Map({
          container: 'view',
          style: {
            version: 8,
            sources: { vtex: { type: 'raster', url } },
            layers: [{ id: 'vtex', type: 'raster', source: 'vtex', paint: { 'raster-resampling': 'nearest', 'raster-fade-duration': 0 } }],
          },
          attributionControl: false,
          fadeDuration: 0,
          renderWorldCopies: false,
          maxZoom: 24,
          // Starting at full resolution: a first view at zoom 0 would fetch a zoom never checked.
          zoom: Math.log2((ts * 2 ** maxzoom) / 512),
        });
        map.on('error', (e) => reject(e.error));
        map.once('load', resolve);
        // Level L is the Web Mercator world at ts · 2^(maxzoom − L) texels across; MapLibre's
        // zoom z draws that world 512 · 2^z screen pixels across.
        let world;
        const at = (x, y) => map.project(new MercatorCoordinate(x / world, y / world).toLngLat());
        window.goTo = (level, x, y) =>
          new Promise((drawn) => {
            world = ts * 2 ** (maxzoom - level);
            map.once('idle', drawn);
            map.jumpTo({ center: new MercatorCoordinate(x / world, y / world).toLngLat(), zoom: Math.log2(world / 512) });
          });
        window.screenOf = (x, y) => {
          const [a, b] = [at(x, y), at(x + 100, y + 100)];
          return { ax: a.x, ay: a.y, sx: (b.x - a.x) / 100, sy: (b.y - a.y) / 100 };
        };
      }),
    [`${server.url}/api/v1/textures/${big.id}/tilejson.json`, big.tile_size, big.levels - 1],
  );
  await showsTheServersPixels(page, 'MapLibre');
  assert.deepEqual(xyzZooms(log.requests), ZOOMS(), 'MapLibre fetched the zooms of the levels it shows');
  assert.deepEqual(log.errors, []);
  assert.deepEqual(log.bad, []);
  await page.close();
});

test("Leaflet shows the 100k texture's XYZ layer from its TileJSON: the server's pixels, edges included", async () => {
  const tj = await (await fetch(`${server.url}/api/v1/textures/${big.id}/tilejson.json`)).json();
  const { page, log } = await blankPage(LEAFLET);
  await page.evaluate((tj) => {
    const map = L.map('view', { zoomControl: false, attributionControl: false, fadeAnimation: false, zoomAnimation: false });
    const [west, south, east, north] = tj.bounds;
    const layer = L.tileLayer(tj.tiles[0], {
      minZoom: tj.minzoom,
      maxZoom: tj.maxzoom,
      tileSize: tj.tileSize,
      noWrap: true,
      bounds: L.latLngBounds([south, west], [north, east]),
    }).addTo(map);
    // At zoom maxzoom − L a map pixel is a texel of level L: level point (x, y) is map pixel (x, y).
    let zoom;
    window.goTo = (level, x, y) =>
      new Promise((drawn) => {
        zoom = tj.maxzoom - level;
        layer.once('load', drawn);
        map.setView(map.unproject([x, y], zoom), zoom, { animate: false });
      });
    window.screenOf = (x, y) => {
      const p = map.latLngToContainerPoint(map.unproject([x, y], zoom));
      return { ax: p.x, ay: p.y, sx: 1, sy: 1 };
    };
  }, tj);
  await showsTheServersPixels(page, 'Leaflet');
  assert.deepEqual(xyzZooms(log.requests), ZOOMS(), 'Leaflet fetched the zooms of the levels it shows');
  assert.deepEqual(log.errors, []);
  assert.deepEqual(log.bad, []);
  await page.close();
});

test("OpenLayers shows the 100k texture's XYZ layer in a texel projection: the server's pixels, edges included", async () => {
  const tj = await (await fetch(`${server.url}/api/v1/textures/${big.id}/tilejson.json`)).json();
  const { page, log } = await blankPage(OL);
  await page.evaluate(
    ([tj, width, height]) => {
      // One unit a level-0 texel, y up, so the texture is [0, −height, width, 0]; zoom z has
      // 2^(maxzoom − z) units a pixel.
      const extent = [0, -height, width, 0];
      const projection = new ol.proj.Projection({ code: 'vtex-texels', units: 'pixels', extent });
      const resolutions = Array.from({ length: tj.maxzoom + 1 }, (_, z) => 2 ** (tj.maxzoom - z));
      const tileGrid = new ol.tilegrid.TileGrid({ origin: [0, 0], extent, resolutions, tileSize: tj.tileSize });
      const source = new ol.source.XYZ({ url: tj.tiles[0], projection, tileGrid, interpolate: false, transition: 0 });
      const view = new ol.View({ projection, resolutions });
      const map = new ol.Map({ target: 'view', layers: [new ol.layer.Tile({ source })], view, controls: [], interactions: [] });
      let s;
      window.goTo = (level, x, y) =>
        new Promise((drawn) => {
          s = 2 ** level;
          map.once('rendercomplete', drawn);
          view.setResolution(s);
          view.setCenter([x * s, -y * s]);
        });
      window.screenOf = (x, y) => {
        const [ax, ay] = map.getPixelFromCoordinate([x * s, -y * s]);
        return { ax, ay, sx: 1, sy: 1 };
      };
    },
    [tj, big.width, big.height],
  );
  await showsTheServersPixels(page, 'OpenLayers');
  assert.deepEqual(xyzZooms(log.requests), ZOOMS(), 'OpenLayers fetched the zooms of the levels it shows');
  assert.deepEqual(log.errors, []);
  assert.deepEqual(log.bad, []);
  await page.close();
});
