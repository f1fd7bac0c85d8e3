// Assembles the package for `npm pack` (its prepack script): the JavaScript wrapper from its one
// source, the viewer's client-web/src/shared/vtex-synth.js, and every model's WebAssembly module
// as scripts/build-wasm writes them (target/wasm-modules/vtex_synth_<model>.wasm) into wasm/.
import { copyFileSync, existsSync, mkdirSync, readdirSync, rmSync } from 'node:fs';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
const root = join(here, '..', '..');
const modules = join(root, 'target', 'wasm-modules');

const built = existsSync(modules) ? readdirSync(modules).filter((n) => /^vtex_synth_[a-z0-9-]+\.wasm$/.test(n)) : [];
if (built.length === 0) {
  console.error(`no module in ${modules}: run scripts/build-wasm first`);
  process.exit(1);
}
copyFileSync(join(root, 'client-web', 'src', 'shared', 'vtex-synth.js'), join(here, 'vtex-synth.js'));
rmSync(join(here, 'wasm'), { recursive: true, force: true });
mkdirSync(join(here, 'wasm'));
for (const name of built) copyFileSync(join(modules, name), join(here, 'wasm', name));
console.log(`vtex-synth: the wrapper and ${built.length} modules (${built.join(', ')})`);
