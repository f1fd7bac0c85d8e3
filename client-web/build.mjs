// Builds client-web/dist/: src/ as it is — the pages at its root (index.html, the viewer, at
// `/`; vt.html, the VT demo), their code in its folders (viewer/, vt/, workers/, shared/; the
// modules import each other relatively, so the tree is served as it is, with no bundler) — plus
// OpenSeadragon and its navigation images copied from node_modules (the server serves this
// directory at `/`; nothing comes from a CDN), and the synthesis modules for client mode, one
// per model (`vtex_synth_<model>.wasm`, built into target/wasm-modules/ by `scripts/build-wasm`).
// Every text file and the modules get a brotli (quality 11) and a gzip (level 9) copy beside
// them, `X.br` and `X.gz`, which vtex (embedded or --web-dir) and any static server that looks
// for such copies (nginx's gzip_static) send to clients that accept them. Not the pages: vtex
// (and `vtex export-web`, the viewer's) rewrite them.
import { cpSync, existsSync, mkdirSync, readdirSync, readFileSync, rmSync, statSync, writeFileSync } from 'node:fs';
import { dirname, extname, join, posix } from 'node:path';
import { fileURLToPath } from 'node:url';
import { brotliCompressSync, constants, gzipSync } from 'node:zlib';

const here = dirname(fileURLToPath(import.meta.url));
const src = join(here, 'src');
const dist = join(here, 'dist');
const osd = join(here, 'node_modules', 'openseadragon', 'build', 'openseadragon');
const modules = join(here, '..', 'target', 'wasm-modules');

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
const built = existsSync(modules) ? readdirSync(modules).filter((n) => /^vtex_synth_.+\.wasm$/.test(n)) : [];
for (const name of built) cpSync(join(modules, name), join(dist, name));
if (built.length === 0) console.warn(`no module in ${modules} (scripts/build-wasm): the viewer's client mode (?synth=client) will say so`);

/** The modules that module `entry` (a path below src/) imports statically, transitively. */
function importsOf(entry, seen = new Set()) {
  const code = readFileSync(join(src, entry), 'utf8');
  for (const [, spec] of code.matchAll(/^import\s[^'"]*?['"](\.{1,2}\/[^'"]+)['"]/gm)) {
    const path = posix.normalize(posix.join(posix.dirname(entry), spec));
    if (!seen.has(path)) {
      seen.add(path);
      importsOf(path, seen);
    }
  }
  return seen;
}

// Each page names every module its scripts import (`modulepreload`), so the browser fetches
// them at once instead of discovering them an import (a round trip) at a time.
for (const page of readdirSync(src).filter((n) => n.endsWith('.html'))) {
  const html = readFileSync(join(src, page), 'utf8').replace(/^( *)(<script src="([^"]+)" type="module"><\/script>)$/gm, (_, indent, tag, entry) =>
    [...importsOf(entry)].map((m) => `${indent}<link rel="modulepreload" href="${m}">\n`).join('') + indent + tag,
  );
  writeFileSync(join(dist, page), html);
}

const COMPRESSIBLE = new Set(['.js', '.mjs', '.css', '.wasm', '.json', '.svg', '.map', '.txt']);

/** Writes the compressed copies of `path`, each only where it saves at least a tenth. */
function precompress(path) {
  const bytes = readFileSync(path);
  const br = brotliCompressSync(bytes, {
    params: { [constants.BROTLI_PARAM_QUALITY]: 11, [constants.BROTLI_PARAM_LGWIN]: 24, [constants.BROTLI_PARAM_SIZE_HINT]: bytes.length },
  });
  const gz = gzipSync(bytes, { level: 9 });
  for (const [ext, copy] of [['.br', br], ['.gz', gz]]) if (copy.length * 10 < bytes.length * 9) writeFileSync(path + ext, copy);
}

function precompressTree(dir) {
  for (const name of readdirSync(dir)) {
    const path = join(dir, name);
    if (statSync(path).isDirectory()) precompressTree(path);
    else if (COMPRESSIBLE.has(extname(name))) precompress(path);
  }
}
precompressTree(dist);
console.log(`built ${dist}`);
