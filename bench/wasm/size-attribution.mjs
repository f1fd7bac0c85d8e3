// Where a module's brotli bytes go: for each group of functions (by name), the brotli size of the
// module with those functions' bodies zeroed, subtracted from the whole module's; and the same for
// the CRC-32 tables in its data (the PNG decoder's: 1 KiB each, slice-by-n runs of n of them). What a group costs compressed, which its raw size
// (`twiggy top`) does not tell: brotli shares much between similar functions.
//
// Needs a module with its function names (the `name` section), built as scripts/build-wasm
// builds it but not stripped:
//
//   CARGO_PROFILE_WASM_STRIP=false cargo build -p vtex-synth-wasm --lib --target wasm32-unknown-unknown \
//       --profile wasm --no-default-features --features model-patterns
//   node bench/wasm/size-attribution.mjs target/wasm32-unknown-unknown/wasm/vtex_synth_wasm.wasm
//
// Custom sections (names, debug info) are left out of every size, as the stripped module has none.
import { readFileSync } from 'node:fs';
import { brotliCompressSync, constants } from 'node:zlib';

/** Groups in order: a function is in the first whose pattern its demangled name matches. */
const GROUPS = [
  ['PNG decoding (zune-png, zune-inflate, zune-core)', /png|zune|inflate|fdeflate|crc32|adler/],
  ['JSON and parameters (serde, serde_json, derived impls)', /serde|Deserial|Serializ|Visitor|MapAccess|SeqAccess/],
  ['BLAKE3 (the texture id)', /blake3/],
  ['formatting and panics', /core::fmt|flt2dec|core::num|panic|Display|Debug|fmt::/],
  ['collections and sorting (BTreeMap, slice sorts)', /btree|slice::sort/],
  ['allocator and memory', /dlmalloc|alloc::|raw_vec|memcpy|memset|memmove/],
  ['libm', /libm/],
  ['the model (vtex_synth::models)', /vtex_synth::models::/],
  ["the rest of vtex-synth, vtex-wire, the module's API", /vtex_/],
];
const OTHER = 'other (core, std, glue)';

const brotli = (bytes) =>
  brotliCompressSync(bytes, {
    params: { [constants.BROTLI_PARAM_QUALITY]: 11, [constants.BROTLI_PARAM_LGWIN]: 24, [constants.BROTLI_PARAM_SIZE_HINT]: bytes.length },
  }).length;

/** An unsigned LEB128 at `at`: its value and the offset after it. */
function leb(bytes, at) {
  let value = 0;
  for (let shift = 0; ; shift += 7) {
    const b = bytes[at++];
    value += (b & 0x7f) * 2 ** shift;
    if (b < 0x80) return [value, at];
  }
}

/** A legacy-mangled Rust symbol (`_ZN…E`) as a path; other names as they are. */
function demangle(name) {
  const m = /^_ZN(.*)E$/.exec(name);
  if (!m) return name;
  const parts = [];
  for (let s = m[1]; /^\d/.test(s); ) {
    const [digits] = /^\d+/.exec(s);
    parts.push(s.slice(digits.length, digits.length + Number(digits)));
    s = s.slice(digits.length + Number(digits));
  }
  const escapes = { $LT$: '<', $GT$: '>', $u20$: ' ', $RF$: '&', $C$: ',', $BP$: '*', '..': '::' };
  return parts.join('::').replace(/\$LT\$|\$GT\$|\$u20\$|\$RF\$|\$C\$|\$BP\$|\.\./g, (e) => escapes[e]);
}

const bytes = readFileSync(process.argv[2] ?? '');
const sections = [];
for (let at = 8; at < bytes.length; ) {
  const id = bytes[at];
  const [size, body] = leb(bytes, at + 1);
  sections.push({ id, start: at, body, end: body + size });
  at = body + size;
}
const count = (id, f) => sections.filter((s) => s.id === id).forEach(f);

let imported = 0;
count(2, ({ body }) => {
  let [n, at] = leb(bytes, body);
  for (; n > 0; n--) {
    for (let k = 0; k < 2; k++) {
      const [len, next] = leb(bytes, at);
      at = next + len;
    }
    const kind = bytes[at++];
    // A function's type index; a table's element type, then limits; limits; a global's type.
    const limits = (p) => (bytes[p] & 1 ? leb(bytes, leb(bytes, p + 1)[1])[1] : leb(bytes, p + 1)[1]);
    if (kind === 0) [, at] = leb(bytes, at), imported++;
    else if (kind === 1) at = limits(at + 1);
    else if (kind === 2) at = limits(at);
    else at += 2;
  }
});
const names = new Map();
count(0, ({ body, end }) => {
  let [len, at] = leb(bytes, body);
  if (bytes.toString('utf8', at, at + len) !== 'name') return;
  for (at += len; at < end; ) {
    const sub = bytes[at];
    const [size, start] = leb(bytes, at + 1);
    if (sub === 1) {
      let [n, p] = leb(bytes, start);
      for (; n > 0; n--) {
        const [index, q] = leb(bytes, p);
        const [l, r] = leb(bytes, q);
        names.set(index, demangle(bytes.toString('utf8', r, r + l)));
        p = r + l;
      }
    }
    at = start + size;
  }
});
if (names.size === 0) throw new Error('no function names: build the module with CARGO_PROFILE_WASM_STRIP=false');
const functions = [];
count(10, ({ body }) => {
  let [n, at] = leb(bytes, body);
  for (let i = 0; i < n; i++) {
    const [size, start] = leb(bytes, at);
    const name = names.get(imported + i) ?? '';
    functions.push({ start, end: start + size, group: GROUPS.find(([, re]) => re.test(name))?.[0] ?? OTHER });
    at = start + size;
  }
});

/** The module without custom sections, with the byte ranges `zeroed` cleared. */
function module(zeroed) {
  const copy = Buffer.from(bytes);
  for (const [start, end] of zeroed) copy.fill(0, start, end);
  return Buffer.concat([copy.subarray(0, 8), ...sections.filter((s) => s.id !== 0).map((s) => copy.subarray(s.start, s.end))]);
}
const whole = brotli(module([]));
console.log(`${whole} B brotli without custom sections\n\n| group | raw | brotli |\n|---|---|---|`);
for (const group of [...GROUPS.map(([g]) => g), OTHER]) {
  const ranges = functions.filter((f) => f.group === group).map((f) => [f.start, f.end]);
  const raw = ranges.reduce((s, [a, b]) => s + b - a, 0);
  console.log(`| ${group} | ${raw} B | ${whole - brotli(module(ranges))} B |`);
}
// CRC-32 tables: T0[i] the CRC of byte i, T(k)[i] = T(k-1)[i] >> 8 ^ T0[T(k-1)[i] & 255], little-endian.
const crcTables = [];
for (let k = 0; k < 16; k++) {
  const t = Buffer.alloc(1024);
  for (let i = 0; i < 256; i++) {
    let c;
    if (k === 0) {
      c = i;
      for (let b = 0; b < 8; b++) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
    } else {
      const p = crcTables[k - 1].readUInt32LE(4 * i);
      c = (p >>> 8) ^ crcTables[0].readUInt32LE(4 * (p & 255));
    }
    t.writeUInt32LE(c >>> 0, 4 * i);
  }
  crcTables.push(t);
}
const tables = [];
for (let at = bytes.indexOf(crcTables[0]); at >= 0; ) {
  let end = at + 1024;
  for (let k = 1; k < 16 && bytes.subarray(end, end + 1024).equals(crcTables[k]); k++) end += 1024;
  tables.push([at, end]);
  at = bytes.indexOf(crcTables[0], end);
}
const tableBytes = tables.reduce((s, [a, b]) => s + b - a, 0);
console.log(`| CRC-32 tables, in the data (${tables.map(([a, b]) => `${(b - a) / 1024} KiB`).join(' + ') || 'none'}) | ${tableBytes} B | ${whole - brotli(module(tables))} B |`);
