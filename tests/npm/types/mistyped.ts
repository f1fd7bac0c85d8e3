// The same calls with the mistakes a user could make: tsc --strict must refuse exactly the lines
// marked `wrong` (tests/npm/package.test.mjs), which shows the package's types are checked.
import { instantiate, loadModule, SynthError } from 'vtex-synth';
import type { TextureInfo } from 'vtex-synth';

export async function firstTile(api: string): Promise<void> {
  const info: TextureInfo = await (await fetch(api)).json();
  const encoding = await (await fetch(`${api}/encoding`)).arrayBuffer();
  const synth = await instantiate(await loadModule(info));                // wrong: the info, not its model
  const texture = synth.open(encoding);                                   // wrong: no tile size
  const tile = texture.renderTile(0, 0, '0');                             // wrong: a string coordinate
  const bytes: string = tile.data;                                        // wrong: RGBA bytes are no string
  texture.render({ level: 0, x: 0, y: 0, width: 4 });                     // wrong: no height
  const size: string = info.tile_size;                                    // wrong: a number
  texture.info = info;                                                    // wrong: read-only
  const error = new SynthError();                                         // wrong: no message
  console.log(bytes, size, error, info.colour);                           // wrong: no such field
}
