// Builds client-web/dist/: the viewer's files plus OpenSeadragon and its navigation images
// copied from node_modules (the server serves this directory at `/`; nothing comes from a CDN).
import { cpSync, existsSync, mkdirSync, readdirSync, rmSync } from 'node:fs';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
const src = join(here, 'src');
const dist = join(here, 'dist');
const osd = join(here, 'node_modules', 'openseadragon', 'build', 'openseadragon');

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
console.log(`built ${dist}`);
