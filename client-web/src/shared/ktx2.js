// The KTX2 container as vtex's pages use it (server/src/ktx2.rs): read the header and the level
// index, hand back level 0's block data for compressedTexSubImage2D. Pure, tested in Node.

const IDENTIFIER = [0xab, 0x4b, 0x54, 0x58, 0x20, 0x32, 0x30, 0xbb, 0x0d, 0x0a, 0x1a, 0x0a];
/** Vulkan formats of vtex's block-compressed pages (sRGB: vtex's pixels are sRGB; normal pages are linear, UNORM). */
export const VK_FORMAT_BC1_RGBA_SRGB = 134;
export const VK_FORMAT_BC7_UNORM = 145;
export const VK_FORMAT_BC7_SRGB = 146;

/** { vkFormat, width, height, levels: [{ offset, length }], data(level) } of a KTX2 file. */
export function parseKtx2(bytes) {
  if (bytes.length < 80 || IDENTIFIER.some((b, i) => bytes[i] !== b)) throw new Error('not a KTX2 file');
  const v = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const vkFormat = v.getUint32(12, true);
  const width = v.getUint32(20, true);
  const height = v.getUint32(24, true);
  const levelCount = Math.max(1, v.getUint32(40, true));
  const supercompression = v.getUint32(44, true);
  if (supercompression !== 0) throw new Error(`KTX2 supercompression scheme ${supercompression} is not read here`);
  if (bytes.length < 80 + 24 * levelCount) throw new Error('KTX2 level index is cut short');
  const levels = [];
  for (let i = 0; i < levelCount; i++) {
    const offset = Number(v.getBigUint64(80 + 24 * i, true));
    const length = Number(v.getBigUint64(88 + 24 * i, true));
    if (offset + length > bytes.length) throw new Error(`KTX2 level ${i} lies past the end of the file`);
    levels.push({ offset, length });
  }
  return { vkFormat, width, height, levels, data: (i) => bytes.subarray(levels[i].offset, levels[i].offset + levels[i].length) };
}
