// docs/bandwidth.md and docs/bandwidth.svg from a run of bench/bandwidth.mjs (its JSON).
import { PROFILES } from './sessions.mjs';

const MB = (n) => (n >= 1e9 ? `${(n / 1e9).toFixed(2)} GB` : n >= 1e6 ? `${(n / 1e6).toFixed(2)} MB` : `${(n / 1e3).toFixed(1)} kB`);
const sec = (ms) => (ms === undefined || ms === null ? '–' : `${(ms / 1000).toFixed(2)} s`);
const times = (a, b) => (b > 0 ? `${(a / b).toFixed(a / b >= 100 ? 0 : 1)}×` : '–');
const visit = (r) => (r.returning ? 'returning' : 'first');
const end = (r, views) => (r.complete ? sec(r.endMs) : `cut at ${sec(r.endMs)}${views ? ` (${r.views}/${views} views)` : ''}`);

/** The paper's storage arithmetic (§3.1–3.3) beside the 100k chaos mosaic's encoding. */
function paperSection(mosaic) {
  const m = 5000;
  const n = 128;
  const blocks = (12 * m * m) / (n * n);
  const sample = n * n * 3;
  const lines = [
    "## The paper's arithmetic",
    '',
    `- One random block per tile costs 12 bytes, so an m × m texture from an n × n sample needs 12·m²/n² bytes of blocks: for m = ${m}, n = ${n}, ${Math.round(blocks).toLocaleString('en-US')} B; with the 24-bit sample (${sample.toLocaleString('en-US')} B) ${Math.round(blocks + sample).toLocaleString('en-US')} B — the paper's "about 67 Kb".`,
    `- The explicit ${m}² texture is ${(m * m * 3).toLocaleString('en-US')} B, n²/4 = ${((m * m * 3) / blocks).toFixed(0)} times the blocks (the paper's "4,000 times smaller"), ${((m * m * 3) / (blocks + sample)).toFixed(0)} times blocks and sample.`,
  ];
  if (mosaic) {
    const mm = mosaic.width;
    const nn = mm / 625;
    lines.push(
      `- The 100k chaos mosaic here (m = ${mm.toLocaleString('en-US')}, n = ${nn}, two blocks per tile): 12·m²/n²·2 = ${MB((12 * mm * mm * 2) / (nn * nn))} of blocks if they were stored; vtex derives them from a seed and stores the sample as PNG, so the whole encoding is ${mosaic.encoding_bytes.toLocaleString('en-US')} B, ${Math.round(mosaic.explicit_bytes / mosaic.encoding_bytes).toLocaleString('en-US')} times smaller than the explicit 24-bit level 0 (${MB(mosaic.explicit_bytes)}).`,
    );
  }
  return lines.join('\n');
}

/** The fastest first view among the server's formats under `profile`, and client mode's on a first and a returning visit. */
function firstViews(rows, profile) {
  const at = rows.filter((r) => r.profile === profile);
  const server = at.filter((r) => r.mode !== 'client' && r.firstViewMs !== undefined).sort((a, b) => a.firstViewMs - b.firstViewMs)[0];
  const first = at.find((r) => r.mode === 'client' && !r.returning);
  const returning = at.find((r) => r.mode === 'client' && r.returning);
  return `${server ? `${server.mode} ${sec(server.firstViewMs)}` : '–'} / ${sec(first?.firstViewMs)} / ${sec(returning?.firstViewMs)}`;
}

/** Per model and for the world: first views, the session's bytes on a first visit, the long session's on a returning one. */
function summary(run) {
  const out = [
    '| texture | first complete view at 10 Mbit/s: fastest server format / client, first visit / client, returning | session bytes, first visit: smallest server format / client | ratio (target ≥ 10×) | long session bytes, returning visitor: jpg / client | ratio (target ≥ 100×) | explicit JPEG pyramid : encoding |',
    '|---|---|---|---|---|---|---|',
  ];
  for (const [model, { rows, long, info, explicit }] of Object.entries(run.models)) {
    const ref = rows.filter((r) => r.profile === (rows.some((x) => x.profile === '10mbit') ? '10mbit' : rows[0].profile) && !r.returning);
    const server = ref.filter((r) => r.mode !== 'client' && r.complete).sort((a, b) => a.total - b.total)[0];
    const client = ref.find((r) => r.mode === 'client');
    const [longJpg, longClient] = ['jpg', 'client'].map((m) => long.find((r) => r.mode === m));
    out.push(
      `| ${model} | ${firstViews(rows, '10mbit')} | ${server ? `${server.mode} ${MB(server.total)}` : '–'} / ${client ? MB(client.total) : '–'} | ${server && client ? times(server.total, client.total) : '–'} | ${longJpg && longClient ? `${MB(longJpg.total)} / ${MB(longClient.total)}` : '–'} | ${longJpg && longClient ? times(longJpg.total, longClient.total) : '–'} | ${times(explicit.jpg, info.encoding_bytes)} |`,
    );
  }
  if (run.world) {
    const ref = run.world.rows.filter((r) => r.profile === '10mbit' && !r.returning);
    const server = ref.filter((r) => r.mode !== 'client').sort((a, b) => a.total - b.total)[0];
    const client = ref.find((r) => r.mode === 'client');
    out.push(
      `| the 3D world (first complete frame; the walk) | ${firstViews(run.world.rows, '10mbit')} | ${server ? `${server.mode} ${MB(server.total)}` : '–'} / ${client ? MB(client.total) : '–'} | ${server && client ? times(server.total, client.total) : '–'} | – | – | – |`,
    );
  }
  return out.join('\n');
}

function modelSection(model, { info, explicit, rows, long }, run) {
  const out = [`### ${model}: “${info.name}” (${info.width.toLocaleString('en-US')}²)`, ''];
  out.push(
    `Encoding ${info.encoding_bytes.toLocaleString('en-US')} B. Explicit texture, extrapolated from ${explicit.sampled} sampled tiles a format over its ${info.levels} levels: PNG pyramid ≈ ${MB(explicit.png)}, JPEG pyramid ≈ ${MB(explicit.jpg)}; level 0 as raw 24-bit ${MB(explicit.raw24)}.`,
    '',
    '| mode | network | visit | on the wire | tiles | module | encoding | viewer code | requests | first complete view | end of session | client CPU | server CPU |',
    '|---|---|---|---|---|---|---|---|---|---|---|---|---|',
  );
  const line = (r, views) =>
    `| ${r.mode} | ${PROFILES[r.profile].label} | ${visit(r)} | ${MB(r.total)} | ${MB(r.bytes.pixels)} | ${MB(r.bytes.module)} | ${MB(r.bytes.encoding)} | ${MB(r.bytes.code)} | ${Object.values(r.requests).reduce((a, b) => a + b, 0)} | ${sec(r.firstViewMs)} | ${end(r, views)} | ${r.cpu.client.toFixed(1)} s | ${r.cpu.server.toFixed(1)} s |`;
  for (const r of rows) out.push(line(r, run.sessionViews));
  if (long.length) {
    out.push('', `The long session (${run.longViews} views), returning visitor:`, '', out[4], out[5]);
    for (const r of long) out.push(line(r, run.longViews));
  }
  return out.join('\n');
}

function worldSection({ rows, steps }) {
  const out = [
    `The walk: ${steps} frames along the world's scripted path (docs/world.md), starting once the first frame is complete; the floor a 100k chaos mosaic, the walls a cascade texture, the board a patterns texture. A page the walk needs and does not hold yet is drawn from a coarser level, so a slow source shows in the share of needed pages that were resident, not in the walk's length.`,
    '',
    '| pages | network | visit | on the wire | pages | module | encodings | code | requests | first complete frame | end of walk | needed pages resident (mean over the walk) | frame p50 / p95 | client CPU | server CPU |',
    '|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|',
  ];
  const q = (xs, p) => [...xs].sort((a, b) => a - b)[Math.min(xs.length - 1, Math.floor(p * xs.length))] ?? 0;
  for (const r of rows) {
    const walked = r.stats.frameMs.slice(r.stats.frames - r.stats.steps);
    const resident = r.stats.residentShare.length ? r.stats.residentShare.reduce((a, b) => a + b, 0) / r.stats.residentShare.length : 0;
    out.push(
      `| ${r.mode === 'client' ? 'client synthesis' : r.mode === 'ktx2' ? 'BC7 KTX2' : r.mode.toUpperCase()} | ${PROFILES[r.profile].label} | ${visit(r)} | ${MB(r.total)} | ${MB(r.bytes.pixels)} | ${MB(r.bytes.module)} | ${MB(r.bytes.encoding)} | ${MB(r.bytes.code)} | ${Object.values(r.requests).reduce((a, b) => a + b, 0)} | ${sec(r.firstViewMs)} | ${end(r)} | ${(100 * resident).toFixed(1)} % | ${q(walked, 0.5).toFixed(0)} / ${q(walked, 0.95).toFixed(0)} ms | ${r.cpu.client.toFixed(1)} s | ${r.cpu.server.toFixed(1)} s |`,
    );
  }
  return out.join('\n');
}

const COLOURS = { png: '#4e79a7', webp: '#59a14f', jpg: '#f28e2b', rgba: '#bab0ac', ktx2: '#76b7b2', client: '#e15759' };

/** A log-scale bar chart of the bytes of a first visit at 10 Mbit/s (else the first profile run), per model and the world, per mode. */
function plot(run) {
  const groups = Object.entries(run.models).map(([model, v]) => [model, v.rows]);
  if (run.world) groups.push(['3D world', run.world.rows]);
  const profileOf = (rows) => (rows.some((r) => r.profile === '10mbit') ? '10mbit' : rows[0].profile);
  const modes = Object.keys(COLOURS).filter((m) => groups.some(([, rows]) => rows.some((r) => r.mode === m)));
  const W = 1080;
  const H = 380;
  const left = 70;
  const bottom = 300;
  const top = 30;
  const lo = 2; // 100 B: the smallest encodings
  const hi = 9; // 1 GB
  const y = (b) => bottom - ((Math.log10(Math.max(b, 10 ** lo)) - lo) / (hi - lo)) * (bottom - top);
  const group = (W - left - 20) / groups.length;
  const bar = (group - 20) / modes.length;
  const parts = [
    `<svg xmlns="http://www.w3.org/2000/svg" width="${W}" height="${H}" viewBox="0 0 ${W} ${H}" font-family="sans-serif" font-size="12">`,
    `<rect width="${W}" height="${H}" fill="#fff"/>`,
    `<text x="${left}" y="18" font-size="14">Bytes on the wire, first visit (log scale): a pan-and-zoom session per model, the 3D world's walk; server pixels by format vs client synthesis</text>`,
  ];
  for (let e = lo; e <= hi; e++) {
    const label = ['100 B', '1 kB', '10 kB', '100 kB', '1 MB', '10 MB', '100 MB', '1 GB'][e - lo];
    parts.push(`<line x1="${left}" x2="${W - 20}" y1="${y(10 ** e)}" y2="${y(10 ** e)}" stroke="#ddd"/>`);
    parts.push(`<text x="${left - 6}" y="${y(10 ** e) + 4}" text-anchor="end">${label}</text>`);
  }
  groups.forEach(([name, rows], i) => {
    const profile = profileOf(rows);
    modes.forEach((mode, j) => {
      const r = rows.find((x) => x.mode === mode && x.profile === profile && !x.returning);
      if (!r) return;
      const x = left + i * group + 10 + j * bar;
      parts.push(`<rect x="${x.toFixed(1)}" y="${y(r.total).toFixed(1)}" width="${(bar - 2).toFixed(1)}" height="${(bottom - y(r.total)).toFixed(1)}" fill="${COLOURS[mode]}"><title>${name} ${mode}: ${MB(r.total)}</title></rect>`);
      // Inside each bar: what the textures themselves cost (their pixels, or their encodings).
      const own = mode === 'client' ? r.bytes.encoding : r.bytes.pixels;
      parts.push(`<line x1="${x.toFixed(1)}" x2="${(x + bar - 2).toFixed(1)}" y1="${y(own).toFixed(1)}" y2="${y(own).toFixed(1)}" stroke="#000" stroke-width="2" stroke-dasharray="4 2"><title>${name} ${mode}: ${mode === 'client' ? 'encoding' : 'pixels'} ${MB(own)}</title></line>`);
    });
    parts.push(`<text x="${left + i * group + group / 2}" y="${bottom + 18}" text-anchor="middle">${name}</text>`);
  });
  modes.forEach((mode, j) => {
    parts.push(`<rect x="${left + j * 150}" y="${H - 48}" width="12" height="12" fill="${COLOURS[mode]}"/>`);
    parts.push(`<text x="${left + j * 150 + 16}" y="${H - 38}">${mode === 'client' ? 'client synthesis' : mode === 'ktx2' ? 'BC7 KTX2 pages' : `${mode} tiles/pages`}</text>`);
  });
  parts.push(`<line x1="${left}" x2="${left + 18}" y1="${H - 16}" y2="${H - 16}" stroke="#000" stroke-width="2" stroke-dasharray="4 2"/>`);
  parts.push(`<text x="${left + 24}" y="${H - 12}">in each bar: the textures' own bytes, their pixels or their encodings (the rest is code, and the module in client mode)</text>`);
  parts.push(`<text x="${W - 20}" y="${bottom + 34}" text-anchor="end" fill="#555">${PROFILES[profileOf(groups[0][1])].label}</text>`);
  parts.push('</svg>');
  return parts.join('\n');
}

/** docs/bandwidth.md's text and docs/bandwidth.svg's, from a run's figures. */
export function report(run) {
  const { when, commit, chromium, cores, argv, size, cap } = run;
  const loads = Object.entries(run.models)
    .concat(run.world ? [['world', run.world]] : [])
    .map(([m, v]) => `${m} ${v.load.map((l) => l.toFixed(1)).join('→')}`)
    .join(', ');
  const md = [
    '# The bandwidth experiment: server tiles against client synthesis',
    '',
    `Written by \`node bench/bandwidth.mjs ${argv.join(' ')}\` (${when} UTC, commit ${commit}, ${chromium}, ${cores} cores; load average at the start → end of each part: ${loads}). How to read it and what it shows: \`docs/client-synthesis.md\`, "The bandwidth experiment".`,
    '',
    `Session: the whole texture, then ${run.sessionViews - 1} views (zooms to level 0, pans there, jumps, zooms out and in elsewhere), each applied at once after the previous one was complete, in a ${size.width} × ${size.height} viewport. The long session: ${run.longViews} views, a seeded walk of pans, zooms and jumps. Fresh server and browser profile per session; sessions cut at ${cap} s. A first visit starts with an empty HTTP cache; a returning visitor's holds the page's code and the synthesis module (a first visit's URLs, fetched before), which are revalidated, not downloaded.`,
    '',
    paperSection(run.models['chaos-mosaic']?.info),
    '',
    '## Summary',
    '',
    summary(run),
    '',
    '![bytes on the wire per session](bandwidth.svg)',
    '',
    '## Every session',
    '',
    Object.entries(run.models)
      .map(([model, v]) => modelSection(model, v, run))
      .join('\n\n'),
    '',
  ];
  if (run.world) md.push('## The 3D world', '', worldSection(run.world), '');
  return { md: md.join('\n'), svg: plot(run) };
}
