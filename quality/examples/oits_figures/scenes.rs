//! Synthetic stand-ins for the four benchmark scenes of the paper's Fig. 9. The paper fed GL
//! traces through a hardware simulator; here each scene is a ground plane or a cylinder seen by
//! a pinhole camera, rasterized primitive by primitive in scanline order, and every texel read
//! by the filter is one request (repeats included).

/// One texel read: mip level `j` (0 = finest) and texel (x, y) at that level.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Read {
    pub j: u8,
    pub x: i64,
    pub y: i64,
}

pub struct Scene {
    pub name: &'static str,
    /// Side of the square texture (a torus: repeated textures wrap).
    pub texture: u64,
    /// Texel reads in the order the rasterizer issues them.
    pub reads: Vec<Read>,
    /// Levels whose boundary ring of this width (at the finest level) is preloaded.
    pub pinned_border: u64,
}

/// A fragment: screen pixel, texel coordinates at level 0, the primitive drawing it, and the
/// mip level of detail λ.
struct Fragment {
    primitive: u64,
    sx: u32,
    sy: u32,
    u: f64,
    v: f64,
    lod: f64,
}

/// A camera at height `height` above the plane z = 0, at (0, 0), looking along +y and pitched
/// down by `pitch` radians, with focal length `focal` pixels; `density` texels per world unit.
struct Ground {
    width: u32,
    height: u32,
    focal: f64,
    pitch: f64,
    eye: f64,
    density: f64,
    origin: (f64, f64),
}

impl Ground {
    /// Texel coordinates hit by the ray through screen point (sx, sy), if it hits the floor.
    fn hit(&self, sx: f64, sy: f64) -> Option<(f64, f64)> {
        let (dx, dy) = ((sx - self.width as f64 / 2.0) / self.focal, (self.height as f64 / 2.0 - sy) / self.focal);
        let (s, c) = self.pitch.sin_cos();
        let (wy, wz) = (c + dy * s, -s + dy * c);
        if wz >= -1e-9 {
            return None;
        }
        let t = self.eye / -wz;
        Some((self.origin.0 + t * dx * self.density, self.origin.1 + t * wy * self.density))
    }

    /// Every screen pixel that sees the floor, with λ from the screen-space derivatives.
    fn fragments(&self, primitive: impl Fn(f64, f64) -> Option<u64>) -> Vec<Fragment> {
        let mut out = Vec::new();
        for sy in 0..self.height {
            for sx in 0..self.width {
                let (x, y) = (sx as f64 + 0.5, sy as f64 + 0.5);
                let (Some((u, v)), Some((ux, vx)), Some((uy, vy))) =
                    (self.hit(x, y), self.hit(x + 1.0, y), self.hit(x, y + 1.0))
                else {
                    continue;
                };
                let Some(primitive) = primitive(u, v) else { continue };
                let rho = ((ux - u).hypot(vx - v)).max((uy - u).hypot(vy - v));
                out.push(Fragment { primitive, sx, sy, u, v, lod: rho.log2() });
            }
        }
        out
    }
}

/// The four texels bilinear filtering reads at level `j` around level-0 coordinates (u, v).
fn bilinear(j: u8, u: f64, v: f64, out: &mut Vec<Read>) {
    let scale = (1u64 << j) as f64;
    let (x, y) = ((u / scale - 0.5).floor() as i64, (v / scale - 0.5).floor() as i64);
    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
        out.push(Read { j, x: x + dx, y: y + dy });
    }
}

/// Trilinear filtering as GL does it: bilinear at level 0 when magnified, otherwise bilinear
/// at ⌊λ⌋ and ⌊λ⌋ + 1, clamped to the `levels` levels there are.
fn trilinear(levels: u8, f: &Fragment, out: &mut Vec<Read>) {
    let top = levels as f64 - 1.0;
    if f.lod <= 0.0 || f.lod >= top {
        bilinear(f.lod.clamp(0.0, top) as u8, f.u, f.v, out);
    } else {
        let j = f.lod.floor() as u8;
        bilinear(j, f.u, f.v, out);
        bilinear(j + 1, f.u, f.v, out);
    }
}

/// Fragments in rasterization order: primitive by primitive, scanline order inside each.
fn rasterized(mut fragments: Vec<Fragment>) -> Vec<Fragment> {
    fragments.sort_by_key(|f| (f.primitive, f.sy, f.sx));
    fragments
}

/// The triangle of a quad (0 or 1) that local coordinates (a, b) ∈ [0, 1)² fall in.
fn half(a: f64, b: f64) -> u64 {
    (a + b >= 1.0) as u64
}

/// Fig. 6: a 512² textured square in perspective on a 512² screen, tessellated into 64×64
/// quads of two triangles, clipped by the frustum, trilinear over 4 levels.
pub fn polygon() -> Scene {
    let ground =
        Ground { width: 512, height: 512, focal: 400.0, pitch: 0.6, eye: 80.0, density: 1.0, origin: (160.0, -40.0) };
    let quad = 512.0 / 64.0;
    let fragments = ground.fragments(|u, v| {
        if !(0.0..512.0).contains(&u) || !(0.0..512.0).contains(&v) {
            return None;
        }
        let (qx, qy) = ((u / quad) as u64, (v / quad) as u64);
        Some((qy * 64 + qx) * 2 + half(u / quad - qx as f64, v / quad - qy as f64))
    });
    let mut reads = Vec::new();
    for f in rasterized(fragments) {
        trilinear(4, &f, &mut reads);
    }
    Scene { name: "polygon", texture: 512, reads, pinned_border: 0 }
}

/// Fig. 10: a floor of large triangles at 1280×1024, trilinear, with a `texture`² texture
/// repeated over it (64² for quake I, 512² for quake II).
pub fn quake(name: &'static str, texture: u64) -> Scene {
    let ground =
        Ground { width: 1280, height: 1024, focal: 900.0, pitch: 0.45, eye: 40.0, density: 2.0, origin: (256.0, 0.0) };
    let quad = 512.0;
    let fragments = ground.fragments(|u, v| {
        let (qx, qy) = ((u / quad).floor(), (v / quad).floor());
        let primitive = ((qy as i64 + 64) * 128 + qx as i64 + 64) as u64 * 2;
        Some(primitive + half(u / quad - qx, v / quad - qy))
    });
    let mut reads = Vec::new();
    for f in rasterized(fragments) {
        trilinear(4, &f, &mut reads);
    }
    Scene { name, texture, reads, pinned_border: 0 }
}

/// Fig. 11: one 256² tile of a panorama on a cylinder of tall, skinny triangles, seen at
/// 1280×1024, bilinear at the finest level only; its lower part is outside the frustum, and
/// its 16-texel boundary is preloaded so only the central 224² is synthesized.
pub fn qtvr() -> Scene {
    let (width, height, focal) = (1280.0f64, 1024.0f64, 1000.0f64);
    let radius = 800.0;
    let (left, top) = (-128.0, 230.0);
    let strip = 16.0;
    let mut fragments = Vec::new();
    for sy in 0..height as u32 {
        for sx in 0..width as u32 {
            let (x, y) = (sx as f64 + 0.5 - width / 2.0, sy as f64 + 0.5 - height / 2.0);
            let angle = (x / focal).atan();
            let (u, v) = (angle * radius - left, y * angle.cos() * radius / focal - top);
            if !(0.0..256.0).contains(&u) || !(0.0..256.0).contains(&v) {
                continue;
            }
            let s = (u / strip).floor();
            let primitive = s as u64 * 2 + half(u / strip - s, v / 256.0);
            fragments.push(Fragment { primitive, sx, sy, u, v, lod: 0.0 });
        }
    }
    let mut reads = Vec::new();
    for f in rasterized(fragments) {
        bilinear(0, f.u, f.v, &mut reads);
    }
    Scene { name: "qtvr", texture: 256, reads, pinned_border: 16 }
}
