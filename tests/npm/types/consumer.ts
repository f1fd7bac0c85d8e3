// A TypeScript application using vtex-synth as its README shows: tsc --strict accepts it
// (tests/npm/package.test.mjs), resolving the package through its exports map.
import { instantiate, loadModule, moduleFile, moduleUrl, Synth, SynthError } from 'vtex-synth';
import type { Region, SynthTexture, TextureInfo, Tile } from 'vtex-synth';

export async function firstTile(api: string, canvas: HTMLCanvasElement): Promise<TextureInfo> {
  const info: TextureInfo = await (await fetch(api)).json();
  const encoding: ArrayBuffer = await (await fetch(`${api}/encoding`)).arrayBuffer();
  const compiled: WebAssembly.Module = await loadModule(info.model);
  const synth: Synth = await instantiate(compiled);
  const texture: SynthTexture = synth.open(encoding, info.tile_size);
  const tile: Tile = texture.renderTile(0, 0, 0);
  const image = new ImageData(new Uint8ClampedArray(tile.data.buffer), tile.width, tile.height);
  canvas.getContext('2d')?.putImageData(image, 0, 0);
  const region: Region = { level: texture.info.levels - 1, x: -3, y: 5, width: 7, height: 2, frame: 10 };
  const rgba: Uint8Array = texture.render(region);
  texture.close();
  const period: number | undefined = info.animation?.period_frames;
  const domain: 'torus' | 'plane' = info.domain;
  console.log(rgba.length, period, domain, synth.failure?.length, moduleFile(info.model), moduleUrl(info.model, '/assets/').href);
  return texture.info;
}

export async function fromBytes(bytes: Uint8Array, elsewhere: URL): Promise<SynthTexture | string> {
  try {
    const synth = await instantiate(await loadModule('lcm', elsewhere));
    return synth.open(bytes, 256);
  } catch (e) {
    if (e instanceof SynthError) return e.message;
    throw e;
  }
}
