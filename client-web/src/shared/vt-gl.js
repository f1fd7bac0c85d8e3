// Virtual texturing on the GPU (the VT demo, vt.html, and the 3D world, world.html): surfaces seen
// by a perspective camera — the ground plane z = 0, and rectangles (walls, boards) — each textured
// by a virtual texture, drawn twice a frame: a feedback pass into a small framebuffer naming, per
// fragment, the texture, page and level its footprint needs, and the colour pass sampling that
// texture's atlas of resident pages through its page table, trilinearly across the two levels
// around the footprint's level of detail. Both passes compute that level of detail with the same
// function, from the screen-space derivatives of the texel coordinates, as a GPU does for mips.

import { BORDER, FADE_FRAMES, MAX_TEXTURES, PAGE_SIZE, SLOT_SIDE } from './vt-pages.js';

/**
 * Largest anisotropy the 4-pixel border allows: at the finer of the two levels sampled the
 * footprint's major axis spans up to 2N texels, whose N probes and their bilinear taps reach
 * N − ½ texels from the fragment's point.
 */
export const MAX_ANISOTROPY = 4;
/** The depth range of rectangles, in world units (level-0 texels of the ground). */
const NEAR = 1;
const FAR = 1e6;
/** The light a lit surface has from every side, as a share of the direct light's. */
const AMBIENT = 0.3;

// The camera's uniforms, and those of the virtual texture being drawn. `levelOfDetail` is the
// continuous mip level of a footprint: log2 of its minor axis, or of its major axis over the
// anisotropy when the footprint is more elongated than the filter can follow, clamped to the
// levels there are.
const COMMON = `#version 300 es
precision highp float;
precision highp int;
uniform vec3 camPos;
uniform vec3 camForward, camRight, camUp;
uniform vec2 tanHalf;
uniform vec2 viewSize;
uniform vec2 texSize;
uniform float lodBias;
uniform float maxAniso;
uniform int maxLevel;
uniform int texIndex;
const float PAGE = ${PAGE_SIZE}.0;

float levelOfDetail(vec2 dx, vec2 dy) {
  float a = length(dx), b = length(dy);
  float lod = max(log2(max(min(a, b), 1e-30)), log2(max(a, b)) - log2(maxAniso)) - lodBias;
  return clamp(lod, 0.0, float(maxLevel));
}

vec2 pageOf(vec2 wrapped, int level) {
  return floor(wrapped / (exp2(float(level)) * PAGE));
}
`;

/**
 * How a surface's fragments find their level-0 texel coordinates: `vertex` is its vertex
 * shader, `surface(out uv)` (GLSL) answers whether the fragment shows the surface.
 */
const GEOMETRY = {
  // The ground z = 0 under a full-screen triangle: the camera's ray through the fragment meets it
  // at texel `uv` (unwrapped, so derivatives are continuous across a torus's seam).
  ground: {
    vertex: `#version 300 es
void main() {
  vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2);
  gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}`,
    surface: `
bool surface(out vec2 uv) {
  vec2 ndc = gl_FragCoord.xy / viewSize * 2.0 - 1.0;
  vec3 d = camForward + ndc.x * tanHalf.x * camRight + ndc.y * tanHalf.y * camUp;
  uv = camPos.xy - camPos.z / min(d.z, -1e-6) * d.xy;
  return d.z < -1e-6;
}`,
    // Texel x runs along world x, texel y (rows, downwards in the image) along world y: the
    // tangent space's +Y, up the image, is world −y, and +Z is the ground's normal.
    toWorld: `
vec3 toWorld(vec3 n) {
  return vec3(n.x, -n.y, n.z);
}`,
  },
  // A rectangle in the world, its corners' texel coordinates interpolated (perspective-correct),
  // projected with the ground's camera so the two meet exactly.
  quad: {
    vertex: `${COMMON}
in vec3 position;
in vec2 texel;
out vec2 vTexel;
void main() {
  vec3 p = position - camPos;
  float z = dot(p, camForward);
  const float A = ${(FAR + NEAR) / (FAR - NEAR)}, B = ${(-2 * FAR * NEAR) / (FAR - NEAR)};
  gl_Position = vec4(dot(p, camRight) / tanHalf.x, dot(p, camUp) / tanHalf.y, A * z + B, z);
  vTexel = texel;
}`,
    surface: `
in vec2 vTexel;
bool surface(out vec2 uv) {
  uv = vTexel;
  return true;
}`,
  },
};

// Writes the page of the finer of the two levels the colour pass blends (the coarser one's page is
// its ancestor, which residency keeps with it): x and y (12 bits each: low bytes in R and G,
// high nibbles in B), level + 1 and the texture's index in A (vt-pages.js decodeFeedback).
const FEEDBACK = (surface) => `${COMMON}${surface}
out vec4 outColor;
void main() {
  vec2 uv;
  bool seen = surface(uv);
  int level = int(levelOfDetail(dFdx(uv), dFdy(uv)));
  if (!seen) { outColor = vec4(0.0); return; }
  ivec2 p = ivec2(pageOf(mod(uv, texSize), level));
  int high = ((p.x >> 8) & 15) | (((p.y >> 8) & 15) << 4);
  outColor = vec4(float(p.x & 255), float(p.y & 255), float(high), float((texIndex << 4) | (level + 1))) / 255.0;
}`;

// The page table's mip L holds, per page of level L, its atlas slot (R, G) and in A whether it is
// resident: 0 not, 255 shown whole, 128 fading in since frame B (modulo 256), showing
// (age + 1) / FADE_FRAMES of it — so a page's entry is written when it arrives and when it shows
// whole (vt-stream.js), not every frame between. A fragment blends level ⌊lod⌋ and the next
// coarser one by lod's fraction, each level showing as much of its page as is shown and the next
// coarser level (by the same rule) the rest: neither a change of level across the view nor a
// page arriving changes the frame at once. The colour atlas is sRGB, so filtering and blending
// happen in linear light and the result is encoded back to sRGB for the (non-sRGB) canvas. A
// surface that can say where its tangent space lies (`toWorld`) is lit when its texture has a
// normal atlas: Lambert and ambient, the normal blended as the colour is.
const COLOUR = ({ surface, toWorld }) => `${COMMON}${surface}
uniform highp sampler2D pageTable;
uniform highp sampler2D atlas;
uniform highp sampler2D normalAtlas;
uniform bool lit;
uniform vec3 light;
uniform float atlasSide;
uniform int frame;
uniform vec3 sky;
out vec4 outColor;
const float SLOT = ${SLOT_SIDE}.0;
const float BORDER = ${BORDER}.0;
const float AMBIENT = ${AMBIENT};
const float FADE_FRAMES = ${FADE_FRAMES}.0;
${toWorld || ''}

float shown(vec4 entry) {
  if (entry.a > 0.75) return 1.0;
  if (entry.a < 0.25) return 0.0;
  int age = (frame - int(entry.b * 255.0 + 0.5)) & 255;
  return min(1.0, float(age + 1) / FADE_FRAMES);
}

vec3 toSrgb(vec3 c) {
  return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, step(vec3(0.0031308), c));
}

void main() {
  vec2 uv;
  bool seen = surface(uv);
  vec2 dx = dFdx(uv), dy = dFdy(uv);
  if (!seen) { outColor = vec4(sky, 1.0); return; }
  vec2 wrapped = mod(uv, texSize);
  float lod = levelOfDetail(dx, dy);
  int fine = int(lod);
  float toCoarser = lod - float(fine);
  // The weight still to give: the finer level's share, joined by the coarser level's at fine + 1.
  float open = 1.0 - toCoarser;
  vec3 colour = vec3(0.0);
  vec3 normal = vec3(0.0);
  for (int level = fine; level <= maxLevel; level++) {
    if (level == fine + 1) open += toCoarser;
    vec2 page = pageOf(wrapped, level);
    vec4 entry = texelFetch(pageTable, ivec2(page), level);
    float w = open * shown(entry);
    if (w > 0.0) {
      float scale = exp2(-float(level));
      vec2 slot = floor(entry.rg * 255.0 + 0.5);
      vec2 at = (slot * SLOT + BORDER + wrapped * scale - page * PAGE) / atlasSide;
      vec2 gx = dx * scale / atlasSide, gy = dy * scale / atlasSide;
      colour += w * textureGrad(atlas, at, gx, gy).rgb;
      ${toWorld ? 'if (lit) normal += w * (textureGrad(normalAtlas, at, gx, gy).rgb * 2.0 - 1.0);' : ''}
      open -= w;
    }
    if (open <= 0.0 && level > fine) break;
  }
  ${toWorld ? 'if (lit) colour *= AMBIENT + (1.0 - AMBIENT) * max(dot(normalize(toWorld(normal)), light), 0.0);' : ''}
  outColor = vec4(toSrgb(colour), 1.0);
}`;

function compile(gl, vertex, fragment) {
  const program = gl.createProgram();
  for (const [type, src] of [[gl.VERTEX_SHADER, vertex], [gl.FRAGMENT_SHADER, fragment]]) {
    const s = gl.createShader(type);
    gl.shaderSource(s, src);
    gl.compileShader(s);
    if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(`shader: ${gl.getShaderInfoLog(s)}`);
    gl.attachShader(program, s);
  }
  gl.bindAttribLocation(program, 0, 'position');
  gl.bindAttribLocation(program, 1, 'texel');
  gl.linkProgram(program);
  if (!gl.getProgramParameter(program, gl.LINK_STATUS)) throw new Error(`program: ${gl.getProgramInfoLog(program)}`);
  const uniforms = {};
  for (let i = 0; i < gl.getProgramParameter(program, gl.ACTIVE_UNIFORMS); i++) {
    const name = gl.getActiveUniform(program, i).name;
    uniforms[name] = gl.getUniformLocation(program, name);
  }
  return { program, uniforms };
}

/**
 * One virtual texture's GPU state for `pyramid` (vt-pages.js): its page table and an atlas of
 * `slotsPerSide`² slots holding RGBA or BC7 pages (`bc7`: the GPU's
 * EXT_texture_compression_bptc, or null), filtered with up to `anisotropy`; with `normals`, a
 * second atlas of the same slots holding each page's normal page (linear, not sRGB).
 */
export class PhysicalTexture {
  constructor(gl, pyramid, { slotsPerSide, bc7, anisotropy, normals = false }) {
    this.gl = gl;
    this.pyramid = pyramid;
    this.slotsPerSide = slotsPerSide;
    this.atlasSide = slotsPerSide * SLOT_SIDE;
    this.bc7 = bc7;

    this.pageTable = gl.createTexture();
    gl.bindTexture(gl.TEXTURE_2D, this.pageTable);
    gl.texStorage2D(gl.TEXTURE_2D, pyramid.maxLevel + 1, gl.RGBA8, pyramid.tableSide, pyramid.tableSide);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST_MIPMAP_NEAREST);
    gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);

    const aniso = gl.getExtension('EXT_texture_filter_anisotropic');
    this.anisotropy = aniso ? Math.min(anisotropy, gl.getParameter(aniso.MAX_TEXTURE_MAX_ANISOTROPY_EXT)) : 1;
    const atlas = (format) => {
      const t = gl.createTexture();
      gl.bindTexture(gl.TEXTURE_2D, t);
      gl.texStorage2D(gl.TEXTURE_2D, 1, format, this.atlasSide, this.atlasSide);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.LINEAR);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.LINEAR);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_S, gl.CLAMP_TO_EDGE);
      gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_WRAP_T, gl.CLAMP_TO_EDGE);
      if (aniso) gl.texParameterf(gl.TEXTURE_2D, aniso.TEXTURE_MAX_ANISOTROPY_EXT, this.anisotropy);
      return t;
    };
    this.format = bc7 ? bc7.COMPRESSED_SRGB_ALPHA_BPTC_UNORM_EXT : gl.SRGB8_ALPHA8;
    this.atlas = atlas(this.format);
    this.normalFormat = bc7 ? bc7.COMPRESSED_RGBA_BPTC_UNORM_EXT : gl.RGBA8;
    this.normalAtlas = normals ? atlas(this.normalFormat) : null;
    this.entry = new Uint8Array(4);
    /** The frame its stream is at: the age of pages fading in counts from it. */
    this.frame = 0;
  }

  /**
   * Puts a page's pixels (RGBA bytes, an ImageBitmap, or BC7 blocks) into atlas slot `slot`, and
   * its normal page's (`normal`) into the normal atlas's.
   */
  upload(slot, body, normal) {
    this.uploadTo(this.atlas, this.format, slot, body);
    if (this.normalAtlas) this.uploadTo(this.normalAtlas, this.normalFormat, slot, normal);
  }

  uploadTo(atlas, format, slot, body) {
    const gl = this.gl;
    const x = (slot % this.slotsPerSide) * SLOT_SIDE;
    const y = Math.floor(slot / this.slotsPerSide) * SLOT_SIDE;
    gl.bindTexture(gl.TEXTURE_2D, atlas);
    if (this.bc7) {
      gl.compressedTexSubImage2D(gl.TEXTURE_2D, 0, x, y, SLOT_SIDE, SLOT_SIDE, format, body);
    } else if (body instanceof ImageBitmap) {
      gl.pixelStorei(gl.UNPACK_COLORSPACE_CONVERSION_WEBGL, gl.NONE);
      gl.texSubImage2D(gl.TEXTURE_2D, 0, x, y, SLOT_SIDE, SLOT_SIDE, gl.RGBA, gl.UNSIGNED_BYTE, body);
      body.close();
    } else {
      gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
      gl.texSubImage2D(gl.TEXTURE_2D, 0, x, y, SLOT_SIDE, SLOT_SIDE, gl.RGBA, gl.UNSIGNED_BYTE, body);
    }
  }

  /**
   * Points page (level, x, y)'s page-table entry at atlas slot `slot`, shown whole, or fading in
   * since frame `fadingSince` (the colour pass counts its age from the texture's `frame`), or
   * clears it (null).
   */
  map(level, x, y, slot, fadingSince = null) {
    const gl = this.gl;
    const e = this.entry;
    if (slot === null) e.fill(0);
    else e.set([slot % this.slotsPerSide, Math.floor(slot / this.slotsPerSide), fadingSince === null ? 0 : fadingSince & 255, fadingSince === null ? 255 : 128]);
    gl.bindTexture(gl.TEXTURE_2D, this.pageTable);
    gl.pixelStorei(gl.UNPACK_ALIGNMENT, 1);
    gl.texSubImage2D(gl.TEXTURE_2D, level, x, y, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, e);
  }
}

/**
 * Draws surfaces ({ geometry: 'ground' | 'quad', texture: index into `textures`, vao for a quad })
 * of virtual textures (`textures`: PhysicalTexture) on `gl`'s canvas, with a feedback
 * framebuffer `feedbackScale` times smaller than the view. The ground is drawn first and
 * everything else in front of it (a rectangle standing on the ground hides it), rectangles
 * among themselves by depth.
 */
export class VtRenderer {
  constructor(gl, { feedbackScale }) {
    this.gl = gl;
    this.feedbackScale = feedbackScale;
    this.textures = [];
    this.programs = {};
    for (const [name, g] of Object.entries(GEOMETRY)) {
      this.programs[name] = { feedback: compile(gl, g.vertex, FEEDBACK(g.surface)), colour: compile(gl, g.vertex, COLOUR(g)) };
    }
    this.feedbackTarget = gl.createTexture();
    this.feedbackDepth = gl.createRenderbuffer();
    this.feedbackBuffer = gl.createFramebuffer();
    this.feedbackSize = [0, 0];
    this.feedbackPixels = new Uint8Array(0);
  }

  /** Adds a virtual texture (PhysicalTexture's options); answers its index. */
  addTexture(pyramid, options) {
    if (this.textures.length === MAX_TEXTURES) throw new Error(`at most ${MAX_TEXTURES} virtual textures`);
    this.textures.push(new PhysicalTexture(this.gl, pyramid, options));
    return this.textures.length - 1;
  }

  /** The ground z = 0 textured by texture `texture`. */
  ground(texture) {
    return { geometry: 'ground', texture };
  }

  /**
   * A rectangle with world corners `corners` ([x, y, z] × 4, in order around it) textured by
   * texture `texture`, the corners at level-0 texels `texels` ([u, v] × 4).
   */
  quad(texture, corners, texels) {
    const gl = this.gl;
    const vao = gl.createVertexArray();
    gl.bindVertexArray(vao);
    const buffer = gl.createBuffer();
    gl.bindBuffer(gl.ARRAY_BUFFER, buffer);
    gl.bufferData(gl.ARRAY_BUFFER, new Float32Array([0, 1, 2, 0, 2, 3].flatMap((i) => [...corners[i], ...texels[i]])), gl.STATIC_DRAW);
    gl.enableVertexAttribArray(0);
    gl.vertexAttribPointer(0, 3, gl.FLOAT, false, 20, 0);
    gl.enableVertexAttribArray(1);
    gl.vertexAttribPointer(1, 2, gl.FLOAT, false, 20, 12);
    gl.bindVertexArray(null);
    return { geometry: 'quad', texture, vao };
  }

  setUniforms(program, camera, width, height, lodBias, texture) {
    const gl = this.gl;
    const u = program.uniforms;
    const t = this.textures[texture];
    const yaw = (camera.yaw * Math.PI) / 180;
    const pitch = (camera.pitch * Math.PI) / 180;
    const [sy, cy, sp, cp] = [Math.sin(yaw), Math.cos(yaw), Math.sin(pitch), Math.cos(pitch)];
    const tan = Math.tan((camera.fov * Math.PI) / 360);
    gl.uniform3f(u.camPos, camera.x, camera.y, camera.height);
    gl.uniform3f(u.camForward, sy * cp, -cy * cp, -sp);
    gl.uniform3f(u.camRight, cy, sy, 0);
    gl.uniform3f(u.camUp, sy * sp, -cy * sp, cp);
    gl.uniform2f(u.tanHalf, (tan * width) / height, tan);
    gl.uniform2f(u.viewSize, width, height);
    gl.uniform2f(u.texSize, t.pyramid.width, t.pyramid.height);
    gl.uniform1f(u.lodBias, lodBias);
    gl.uniform1f(u.maxAniso, t.anisotropy);
    gl.uniform1i(u.maxLevel, t.pyramid.maxLevel);
    gl.uniform1i(u.texIndex, texture);
  }

  /** Draws `surfaces` with `pass` ('feedback' or 'colour'), calling `bind(program, texture)` before each. */
  drawSurfaces(pass, surfaces, camera, width, height, lodBias, bind = () => {}) {
    const gl = this.gl;
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    for (const s of [...surfaces].sort((a, b) => (a.geometry === 'ground' ? 0 : 1) - (b.geometry === 'ground' ? 0 : 1))) {
      const p = this.programs[s.geometry][pass];
      gl.useProgram(p.program);
      this.setUniforms(p, camera, width, height, lodBias, s.texture);
      bind(p, this.textures[s.texture]);
      if (s.geometry === 'ground') {
        gl.disable(gl.DEPTH_TEST);
        gl.drawArrays(gl.TRIANGLES, 0, 3);
      } else {
        gl.enable(gl.DEPTH_TEST);
        gl.bindVertexArray(s.vao);
        gl.drawArrays(gl.TRIANGLES, 0, 6);
        gl.bindVertexArray(null);
      }
    }
    gl.disable(gl.DEPTH_TEST);
  }

  /** The feedback pass: the RGBA8 feedback pixels (vt-pages.js decodeFeedback reads them). */
  feedback(camera, width, height, surfaces) {
    const gl = this.gl;
    const w = Math.max(1, Math.ceil(width / this.feedbackScale));
    const h = Math.max(1, Math.ceil(height / this.feedbackScale));
    if (this.feedbackSize[0] !== w || this.feedbackSize[1] !== h) {
      gl.bindTexture(gl.TEXTURE_2D, this.feedbackTarget);
      gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA8, w, h, 0, gl.RGBA, gl.UNSIGNED_BYTE, null);
      gl.bindRenderbuffer(gl.RENDERBUFFER, this.feedbackDepth);
      gl.renderbufferStorage(gl.RENDERBUFFER, gl.DEPTH_COMPONENT24, w, h);
      gl.bindFramebuffer(gl.FRAMEBUFFER, this.feedbackBuffer);
      gl.framebufferTexture2D(gl.FRAMEBUFFER, gl.COLOR_ATTACHMENT0, gl.TEXTURE_2D, this.feedbackTarget, 0);
      gl.framebufferRenderbuffer(gl.FRAMEBUFFER, gl.DEPTH_ATTACHMENT, gl.RENDERBUFFER, this.feedbackDepth);
      this.feedbackSize = [w, h];
      this.feedbackPixels = new Uint8Array(w * h * 4);
    }
    gl.bindFramebuffer(gl.FRAMEBUFFER, this.feedbackBuffer);
    gl.viewport(0, 0, w, h);
    gl.clearColor(0, 0, 0, 0);
    // The same camera at 1/scale the resolution: derivatives are `scale` times larger.
    this.drawSurfaces('feedback', surfaces, camera, w, h, Math.log2(width / w));
    gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, this.feedbackPixels);
    gl.bindFramebuffer(gl.FRAMEBUFFER, null);
    return this.feedbackPixels;
  }

  /**
   * The colour pass into the canvas; `sky` (linear RGB) where no surface is seen; `light` (a
   * unit vector towards the light, world axes) lights the surfaces whose texture has normals.
   */
  draw(camera, width, height, surfaces, { sky = [0.55, 0.68, 0.85], light = null } = {}) {
    const gl = this.gl;
    gl.viewport(0, 0, width, height);
    gl.clearColor(...sky, 1);
    this.drawSurfaces('colour', surfaces, camera, width, height, 0, (p, t) => {
      gl.activeTexture(gl.TEXTURE0);
      gl.bindTexture(gl.TEXTURE_2D, t.pageTable);
      gl.uniform1i(p.uniforms.pageTable, 0);
      gl.activeTexture(gl.TEXTURE1);
      gl.bindTexture(gl.TEXTURE_2D, t.atlas);
      gl.uniform1i(p.uniforms.atlas, 1);
      const lit = light !== null && t.normalAtlas !== null;
      gl.activeTexture(gl.TEXTURE2);
      gl.bindTexture(gl.TEXTURE_2D, lit ? t.normalAtlas : t.atlas);
      gl.uniform1i(p.uniforms.normalAtlas, 2);
      gl.activeTexture(gl.TEXTURE0);
      gl.uniform1i(p.uniforms.lit, lit ? 1 : 0);
      if (lit) gl.uniform3f(p.uniforms.light, ...light);
      gl.uniform1f(p.uniforms.atlasSide, t.atlasSide);
      gl.uniform1i(p.uniforms.frame, t.frame & 255);
      gl.uniform3f(p.uniforms.sky, ...sky);
    });
  }
}
