// Builds client-web/dist/: the viewer's files plus OpenSeadragon and its navigation images
// copied from node_modules (the server serves this directory at `/`; nothing comes from a CDN),
// and the synthesis module for client mode (`vtex_synth.wasm`, built by
// `cargo build -p vtex-synth-wasm --lib --target wasm32-unknown-unknown --profile wasm`).
import { cpSync, existsSync, mkdirSync, readdirSync, rmSync } from 'node:fs';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
const src = join(here, 'src');
const dist = join(here, 'dist');
const osd = join(here, 'node_modules', 'openseadragon', 'build', 'openseadragon');
const wasm = join(here, '..', 'target', 'wasm32-unknown-unknown', 'wasm', 'vtex_synth_wasm.wasm');

if (!existsSync(join(osd, 'openseadragon.min.js'))) {
  console.error('openseadragon is not installed: run `npm ci` in client-web/ first');
  process.exit(1);
}
rmSync(dist, { recursive: true, force: true });
mkdirSync(join(dist, 'osd'), { recursive: true });
for (const name of readdirSync(src)) cpSync(join(src, name), join(dist, name), { recursive: true });
cpSync(join(osd, 'openseadragon.min.js'), join(dist, 'osd', 'openseadragon.min.js'));
cpSync(join(osd, 'images'), join(dist, 'osd', 'images'), { recursive: true });
const license = ['LICENSE.txt', 'LICENSE'].map((n) => join(here, 'node_modules', 'openseadragon', n)).find(existsSync);
if (license) cpSync(license, join(dist, 'osd', 'LICENSE.txt'));
if (existsSync(wasm)) cpSync(wasm, join(dist, 'vtex_synth.wasm'));
else console.warn(`${wasm} is not built: the viewer's client mode (?synth=client) will say so`);
console.log(`built ${dist}`);
