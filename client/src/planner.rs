//! The page-residency planner: which pages a view needs, and which of them to stream next.
//!
//! The same rule as the WebGL demo's (`client-web/src/shared/vt-pages.js`, docs/vt-demo.md):
//!
//! 1. **What the view needs** ([`Feedback`]): page (level, x, y) → how many screen pixels ask for
//!    it and how far the nearest of them is. Either from a GPU feedback pass (its buffer read
//!    back: [`from_samples`], or [`decode_feedback`] for the demo's RGBA8 encoding), or
//!    computed on the CPU from a camera ([`from_camera`]): rays through every `step`-th pixel
//!    meet a textured plane; the texels one pixel spans there (the isotropic rule of GPU
//!    mip selection, `log2` of the longer screen derivative) give the level, the hit's
//!    coordinates at that level the page.
//! 2. **What to fetch** ([`plan`]): each needed page and all its coarser ancestors up to the
//!    level that is one page, less those resident; coarsest first (a missing fine page falls
//!    back to a resident ancestor, so the view is never a hole and sharpens level by level),
//!    then by screen coverage, then by distance; at most `budget` of them.

use crate::{page_grid, page_levels, PageAddr, TextureInfo};
use std::collections::BTreeMap;

/// A 4×4 matrix, row-major: `clip = m · (x, y, z, 1)ᵀ`, OpenGL's clip space (the visible
/// depth range `-w ≤ z ≤ w`; Direct3D's `0 ≤ z ≤ w` lies inside it, so it works too).
pub type Mat4 = [[f64; 4]; 4];

pub fn mul(a: &Mat4, b: &Mat4) -> Mat4 {
    let mut m = [[0.0; 4]; 4];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..4).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    m
}

/// OpenGL's perspective projection: vertical field of view `fov_y` (radians), `aspect`
/// (width / height), near and far planes.
pub fn perspective(fov_y: f64, aspect: f64, near: f64, far: f64) -> Mat4 {
    let f = 1.0 / (fov_y / 2.0).tan();
    [
        [f / aspect, 0.0, 0.0, 0.0],
        [0.0, f, 0.0, 0.0],
        [0.0, 0.0, (far + near) / (near - far), 2.0 * far * near / (near - far)],
        [0.0, 0.0, -1.0, 0.0],
    ]
}

/// The view matrix of an eye at `eye` looking at `target`, `up` giving the screen's up.
pub fn look_at(eye: [f64; 3], target: [f64; 3], up: [f64; 3]) -> Mat4 {
    let f = normalize(sub(target, eye));
    let s = normalize(cross(f, up));
    let u = cross(s, f);
    [
        [s[0], s[1], s[2], -dot(s, eye)],
        [u[0], u[1], u[2], -dot(u, eye)],
        [-f[0], -f[1], -f[2], dot(f, eye)],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
fn normalize(a: [f64; 3]) -> [f64; 3] {
    let l = dot(a, a).sqrt();
    [a[0] / l, a[1] / l, a[2] / l]
}

fn transform(m: &Mat4, v: [f64; 4]) -> [f64; 4] {
    let mut out = [0.0; 4];
    for (i, o) in out.iter_mut().enumerate() {
        *o = (0..4).map(|k| m[i][k] * v[k]).sum();
    }
    out
}

/// The inverse of `m` (Gauss–Jordan with partial pivoting), `None` if it is singular.
fn invert(m: &Mat4) -> Option<Mat4> {
    let mut a = *m;
    let mut inv = [[0.0; 4]; 4];
    for (i, row) in inv.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    for c in 0..4 {
        let p = (c..4).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))?;
        if a[p][c].abs() < 1e-300 {
            return None;
        }
        a.swap(c, p);
        inv.swap(c, p);
        let d = a[c][c];
        for k in 0..4 {
            a[c][k] /= d;
            inv[c][k] /= d;
        }
        for r in 0..4 {
            if r != c {
                let f = a[r][c];
                for k in 0..4 {
                    a[r][k] -= f * a[c][k];
                    inv[r][k] -= f * inv[c][k];
                }
            }
        }
    }
    Some(inv)
}

/// A textured plane: the point of texture coordinates (u, v) is `origin + u·u_axis + v·v_axis`,
/// (0, 0)–(1, 1) being the whole texture (u across its width, v down its height). Only that
/// quad is drawn, unless `repeat`: then the plane is endless and the texture repeats (a torus
/// texture tiles seamlessly).
#[derive(Clone, Copy, Debug)]
pub struct Surface {
    pub origin: [f64; 3],
    pub u_axis: [f64; 3],
    pub v_axis: [f64; 3],
    pub repeat: bool,
}

/// A view of a [`Surface`]: the camera's view-projection, the viewport in pixels, which pixels
/// are sampled (every `step`-th across and down: a feedback buffer `step` times smaller than
/// the view) and a level-of-detail bias (added to `log2` of the footprint, as a sampler's).
#[derive(Clone, Copy, Debug)]
pub struct View {
    pub view_proj: Mat4,
    pub width: u32,
    pub height: u32,
    pub step: u32,
    pub lod_bias: f64,
}

/// How much of the view asks for one page.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Need {
    /// Screen pixels (each sample stands for `step²` of them; a feedback sample for one).
    pub pixels: u64,
    /// The nearest of them, from the eye, in the surface's units (infinite when unknown).
    pub distance: f64,
}

/// Pages a view needs.
pub type Feedback = BTreeMap<PageAddr, Need>;

fn add(feedback: &mut Feedback, addr: PageAddr, pixels: u64, distance: f64) {
    let n = feedback.entry(addr).or_insert(Need { pixels: 0, distance: f64::INFINITY });
    n.pixels += pixels;
    n.distance = n.distance.min(distance);
}

/// The feedback of a GPU pass read back: one (page, fragments) a sample.
pub fn from_samples(samples: impl IntoIterator<Item = (PageAddr, u64)>) -> Feedback {
    let mut f = Feedback::new();
    for (addr, n) in samples {
        add(&mut f, addr, n, f64::INFINITY);
    }
    f
}

/// The WebGL demo's feedback buffer (RGBA8 as its shader writes it: x and y's low bytes in R
/// and G, their high nibbles in B, level + 1 in A's low nibble, the texture's index in A's high
/// nibble; A = 0 where no surface is seen): the pages of texture `texture`.
pub fn decode_feedback(pixels: &[u8], texture: u8) -> Feedback {
    let mut f = Feedback::new();
    for p in pixels.chunks_exact(4) {
        if p[3] == 0 || p[3] >> 4 != texture {
            continue;
        }
        let level = (p[3] & 15) as u32 - 1;
        let x = p[0] as u32 | ((p[2] as u32 & 15) << 8);
        let y = p[1] as u32 | ((p[2] as u32 >> 4) << 8);
        add(&mut f, PageAddr { level, x, y }, 1, f64::INFINITY);
    }
    f
}

/// The coarsest level worth asking for: the first whose pages are one (or the last level).
pub fn top_level(texture: &TextureInfo, page_size: u32) -> u32 {
    let levels = page_levels(texture);
    (0..levels).find(|&l| page_grid(texture, l, page_size) == (1, 1)).unwrap_or(levels - 1)
}

/// Where the ray through a point of normalised device coordinates meets `surface`: the hit
/// and its texture coordinates (`None` when it misses or is behind the eye or past the far
/// plane).
struct Caster {
    vp: Mat4,
    inv: Mat4,
    eye: Option<[f64; 3]>,
    surface: Surface,
    normal: [f64; 3],
    gram: [[f64; 2]; 2],
}

impl Caster {
    fn new(vp: &Mat4, surface: &Surface) -> Option<Caster> {
        let inv = invert(vp)?;
        // The eye is the point the projection sends to (0, 0, z, 0): a point at infinity for an
        // orthographic one.
        let e = transform(&inv, [0.0, 0.0, 1.0, 0.0]);
        let eye = (e[3].abs() > 1e-12).then(|| [e[0] / e[3], e[1] / e[3], e[2] / e[3]]);
        let (u, v) = (surface.u_axis, surface.v_axis);
        let gram = [[dot(u, u), dot(u, v)], [dot(u, v), dot(v, v)]];
        Some(Caster { vp: *vp, inv, eye, surface: *surface, normal: cross(u, v), gram })
    }

    fn unproject(&self, nx: f64, ny: f64, nz: f64) -> [f64; 3] {
        let p = transform(&self.inv, [nx, ny, nz, 1.0]);
        [p[0] / p[3], p[1] / p[3], p[2] / p[3]]
    }

    fn cast(&self, nx: f64, ny: f64) -> Option<([f64; 3], f64, f64)> {
        let (a, b) = (self.unproject(nx, ny, 0.0), self.unproject(nx, ny, 0.5));
        let dir = sub(b, a);
        let denom = dot(self.normal, dir);
        if denom.abs() < 1e-300 {
            return None;
        }
        let t = dot(self.normal, sub(self.surface.origin, a)) / denom;
        let hit = [a[0] + t * dir[0], a[1] + t * dir[1], a[2] + t * dir[2]];
        let clip = transform(&self.vp, [hit[0], hit[1], hit[2], 1.0]);
        if clip[3] <= 0.0 || clip[2] > clip[3] || clip[2] < -clip[3] {
            return None;
        }
        let d = sub(hit, self.surface.origin);
        let (du, dv) = (dot(d, self.surface.u_axis), dot(d, self.surface.v_axis));
        let [[a11, a12], [_, a22]] = self.gram;
        let det = a11 * a22 - a12 * a12;
        let (u, v) = ((a22 * du - a12 * dv) / det, (a11 * dv - a12 * du) / det);
        let inside = (0.0..1.0).contains(&u) && (0.0..1.0).contains(&v);
        if !(self.surface.repeat || inside) {
            return None;
        }
        Some((hit, u, v))
    }
}

/// The pages a `view` of `surface` textured with `texture` needs, as pages of side `page_size`
/// (module docs). Empty when the view-projection is singular or the surface is not seen.
pub fn from_camera(view: &View, surface: &Surface, texture: &TextureInfo, page_size: u32) -> Feedback {
    let mut feedback = Feedback::new();
    let Some(caster) = Caster::new(&view.view_proj, surface) else { return feedback };
    let top = top_level(texture, page_size);
    let (w, h) = (view.width as f64, view.height as f64);
    let step = view.step.max(1);
    let ndc = |px: f64, py: f64| (2.0 * px / w - 1.0, 1.0 - 2.0 * py / h);
    let (tw, th) = (texture.width as f64, texture.height as f64);
    for py in (0..view.height).step_by(step as usize) {
        for px in (0..view.width).step_by(step as usize) {
            let (cx, cy) = (px as f64 + 0.5, py as f64 + 0.5);
            let (nx, ny) = ndc(cx, cy);
            let Some((hit, u, v)) = caster.cast(nx, ny) else { continue };
            // Texels per pixel along the screen's axes, from the neighbouring pixels' hits
            // (forward differences; backward at the viewport's far edges).
            let derivative = |dx: f64, dy: f64| {
                let (nx, ny) = ndc(cx + dx, cy + dy);
                caster.cast(nx, ny).map(|(_, u2, v2)| ((u2 - u) * tw).hypot((v2 - v) * th))
            };
            let ddx = derivative(1.0, 0.0).or_else(|| derivative(-1.0, 0.0));
            let ddy = derivative(0.0, 1.0).or_else(|| derivative(0.0, -1.0));
            let footprint = ddx.unwrap_or(0.0).max(ddy.unwrap_or(0.0));
            let lod = footprint.max(1e-9).log2() + view.lod_bias;
            // A hair of tolerance: a footprint of exactly 2ᵏ texels (k ≥ 0) is level k however
            // the rounding of the rays fell.
            let level = if lod <= 0.0 { 0 } else { ((lod + 1e-6).floor() as u32).min(top) };
            let (cols, rows) = page_grid(texture, level, page_size);
            let level_w = texture.width.div_ceil(1 << level) as f64;
            let level_h = texture.height.div_ceil(1 << level) as f64;
            let (u, v) = (u.rem_euclid(1.0), v.rem_euclid(1.0));
            let x = ((u * level_w / page_size as f64) as u64).min(cols - 1) as u32;
            let y = ((v * level_h / page_size as f64) as u64).min(rows - 1) as u32;
            let distance = caster.eye.map_or(f64::INFINITY, |e| dot(sub(hit, e), sub(hit, e)).sqrt());
            add(&mut feedback, PageAddr { level, x, y }, (step * step) as u64, distance);
        }
    }
    feedback
}

/// A page to fetch, and what asks for it (its own pixels and those of the finer pages it is
/// an ancestor of).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Request {
    pub addr: PageAddr,
    pub pixels: u64,
    pub distance: f64,
}

/// The page of `level` that page `addr` lies in (`level` ≥ `addr.level`).
pub fn ancestor(addr: PageAddr, level: u32) -> PageAddr {
    let d = level - addr.level;
    PageAddr { level, x: addr.x >> d, y: addr.y >> d }
}

/// The pages to fetch for `feedback` (module docs): every needed page and its ancestors up to
/// [`top_level`] that are not `resident`, coarsest first, then by pixels asking, then nearest
/// first (then by address: the order is total), at most `budget`.
pub fn plan(
    feedback: &Feedback,
    texture: &TextureInfo,
    page_size: u32,
    resident: impl Fn(PageAddr) -> bool,
    budget: usize,
) -> Vec<Request> {
    let top = top_level(texture, page_size);
    let mut wanted: BTreeMap<PageAddr, Request> = BTreeMap::new();
    for (&addr, need) in feedback {
        for level in addr.level..=top.max(addr.level) {
            let a = ancestor(addr, level);
            if resident(a) {
                continue;
            }
            let r = wanted.entry(a).or_insert(Request { addr: a, pixels: 0, distance: f64::INFINITY });
            r.pixels += need.pixels;
            r.distance = r.distance.min(need.distance);
        }
    }
    let mut requests: Vec<Request> = wanted.into_values().collect();
    requests.sort_by(|a, b| {
        b.addr
            .level
            .cmp(&a.addr.level)
            .then(b.pixels.cmp(&a.pixels))
            .then(a.distance.total_cmp(&b.distance))
            .then(a.addr.cmp(&b.addr))
    });
    requests.truncate(budget);
    requests
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeSet;

    fn texture(side: u32) -> TextureInfo {
        let json =
            std::fs::read(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../wire/fixtures/texture-info.json"))
                .unwrap();
        let mut t: TextureInfo = serde_json::from_slice(&json).unwrap();
        (t.width, t.height) = (side as u64, side as u64);
        t
    }

    fn addr(level: u32, x: u32, y: u32) -> PageAddr {
        PageAddr { level, x, y }
    }

    /// The 1024² texture on the quad z = 0, one unit a texel, seen straight down from
    /// `height` above its centre through a 90° field of view onto 256² pixels.
    fn straight_down(height: f64, repeat: bool, centre: [f64; 2]) -> (View, Surface) {
        let proj = perspective(std::f64::consts::FRAC_PI_2, 1.0, 1.0, 10_000.0);
        let view = look_at([centre[0], centre[1], height], [centre[0], centre[1], 0.0], [0.0, -1.0, 0.0]);
        let surface = Surface { origin: [0.0; 3], u_axis: [1024.0, 0.0, 0.0], v_axis: [0.0, 1024.0, 0.0], repeat };
        (View { view_proj: mul(&proj, &view), width: 256, height: 256, step: 1, lod_bias: 0.0 }, surface)
    }

    fn pages(f: &Feedback) -> BTreeSet<PageAddr> {
        f.keys().copied().collect()
    }

    /// From 128 up, the view spans 256 texels on 256 pixels: one texel a pixel, level 0, texels
    /// 384–640 across and down — pages 3 and 4 each way, a quarter of the view each. Twice as
    /// high, two texels a pixel: level 1, whose texels 128–384 are its pages 1 and 2.
    #[test]
    fn a_camera_straight_down_needs_the_pages_under_it_at_its_scale() {
        let t = texture(1024);
        let (view, surface) = straight_down(128.0, false, [512.0, 512.0]);
        let f = from_camera(&view, &surface, &t, 128);
        assert_eq!(pages(&f), BTreeSet::from([addr(0, 3, 3), addr(0, 4, 3), addr(0, 3, 4), addr(0, 4, 4)]));
        assert!(f.values().all(|n| n.pixels == 128 * 128), "{f:?}");
        assert!(f.values().all(|n| (n.distance - 128.0).abs() < 1.0), "nearest pixel below the eye: {f:?}");
        let (view, surface) = straight_down(256.0, false, [512.0, 512.0]);
        let f = from_camera(&view, &surface, &t, 128);
        assert_eq!(pages(&f), BTreeSet::from([addr(1, 1, 1), addr(1, 2, 1), addr(1, 1, 2), addr(1, 2, 2)]));
        let biased = View { lod_bias: 1.0, ..view };
        assert_eq!(
            pages(&from_camera(&biased, &surface, &t, 128)),
            BTreeSet::from([addr(2, 0, 0), addr(2, 1, 0), addr(2, 0, 1), addr(2, 1, 1)])
        );
        // A feedback buffer 8 times smaller sees the same pages, each sample 64 pixels.
        let coarse = View { step: 8, ..view };
        let f8 = from_camera(&coarse, &surface, &t, 128);
        assert_eq!(pages(&f8), pages(&f));
        assert!(f8.values().all(|n| n.pixels == 128 * 128));
    }

    /// Over the texture's corner, a quad alone fills a quarter of the view with its first page;
    /// a repeating plane fills the rest with the pages of the opposite edges.
    #[test]
    fn a_repeating_plane_wraps_and_a_quad_ends() {
        let t = texture(1024);
        let (view, quad) = straight_down(128.0, false, [0.0, 0.0]);
        let f = from_camera(&view, &quad, &t, 128);
        assert_eq!(pages(&f), BTreeSet::from([addr(0, 0, 0)]));
        assert_eq!(f[&addr(0, 0, 0)].pixels, 128 * 128);
        let (view, plane) = straight_down(128.0, true, [0.0, 0.0]);
        assert_eq!(
            pages(&from_camera(&view, &plane, &t, 128)),
            BTreeSet::from([addr(0, 0, 0), addr(0, 7, 0), addr(0, 0, 7), addr(0, 7, 7)])
        );
    }

    /// Looking along the ground from low, the far ground is coarser than the near; looking up,
    /// nothing is needed.
    #[test]
    fn distance_coarsens_and_the_sky_needs_nothing() {
        let t = texture(1 << 16);
        let surface =
            Surface { origin: [0.0; 3], u_axis: [65536.0, 0.0, 0.0], v_axis: [0.0, 65536.0, 0.0], repeat: true };
        let proj = perspective(std::f64::consts::FRAC_PI_3, 16.0 / 9.0, 1.0, 1e6);
        let eye = [30_000.0, 30_000.0, 200.0];
        let down = look_at(eye, [31_000.0, 30_000.0, 0.0], [0.0, 0.0, 1.0]);
        let view = View { view_proj: mul(&proj, &down), width: 320, height: 180, step: 4, lod_bias: 0.0 };
        let f = from_camera(&view, &surface, &t, 128);
        let nearest = f.iter().min_by(|a, b| a.1.distance.total_cmp(&b.1.distance)).unwrap();
        let farthest = f.iter().max_by(|a, b| a.1.distance.total_cmp(&b.1.distance)).unwrap();
        assert!(nearest.1.distance >= 200.0);
        assert!(farthest.0.level > nearest.0.level + 2, "{:?} vs {:?}", farthest, nearest);
        let total: u64 = f.values().map(|n| n.pixels).sum();
        assert!(total < 320 * 180, "the sky asks for no page");
        let up = look_at(eye, [31_000.0, 30_000.0, 400.0], [0.0, 0.0, 1.0]);
        let sky = View { view_proj: mul(&proj, &up), ..view };
        assert!(from_camera(&sky, &surface, &t, 128).values().all(|n| n.distance > 200.0));
        let straight_up = look_at(eye, [30_000.0, 30_000.0, 1000.0], [1.0, 0.0, 0.0]);
        let narrow = perspective(0.5, 1.0, 1.0, 1e6);
        let sky = View { view_proj: mul(&narrow, &straight_up), ..view };
        assert!(from_camera(&sky, &surface, &t, 128).is_empty());
    }

    /// A 1024² texture's pages of 128: levels 0–3, level 3 one page. Two level-0 pages asked
    /// for bring their ancestors, coarsest first; the more pixels first within a level; the
    /// resident skipped (not their ancestors); the budget cuts the finest.
    #[test]
    fn the_plan_is_coarse_first_then_by_coverage_within_the_budget() {
        let t = texture(1024);
        assert_eq!(top_level(&t, 128), 3);
        let f = from_samples([(addr(0, 5, 2), 10), (addr(0, 0, 7), 30), (addr(0, 5, 2), 5)]);
        let all: Vec<(PageAddr, u64)> = plan(&f, &t, 128, |_| false, 100).iter().map(|r| (r.addr, r.pixels)).collect();
        assert_eq!(
            all,
            [
                (addr(3, 0, 0), 45),
                (addr(2, 0, 1), 30),
                (addr(2, 1, 0), 15),
                (addr(1, 0, 3), 30),
                (addr(1, 2, 1), 15),
                (addr(0, 0, 7), 30),
                (addr(0, 5, 2), 15),
            ]
        );
        let resident = [addr(3, 0, 0), addr(1, 0, 3)];
        let some: Vec<PageAddr> = plan(&f, &t, 128, |a| resident.contains(&a), 3).iter().map(|r| r.addr).collect();
        assert_eq!(some, [addr(2, 0, 1), addr(2, 1, 0), addr(1, 2, 1)]);
        let done: BTreeSet<PageAddr> = all.iter().map(|r| r.0).collect();
        assert!(plan(&f, &t, 128, |a| done.contains(&a), 100).is_empty(), "all resident: nothing to fetch");
        // Equal levels and pixels: the nearer first.
        let mut near_far = Feedback::new();
        add(&mut near_far, addr(3, 0, 0), 1, 1.0);
        let t2 = texture(2048);
        add(&mut near_far, addr(3, 1, 0), 4, 9.0);
        add(&mut near_far, addr(3, 0, 1), 4, 2.0);
        let order: Vec<PageAddr> = plan(&near_far, &t2, 128, |a| a.level > 3, 10).iter().map(|r| r.addr).collect();
        assert_eq!(order, [addr(3, 0, 1), addr(3, 1, 0), addr(3, 0, 0)]);
    }

    /// The demo's RGBA8 feedback: page (2, 300, 4100 & 0xfff) of texture 1, twice; texture 0's
    /// page and the empty pixel apart.
    #[test]
    fn the_demos_feedback_buffer_decodes() {
        let px = |level: u32, x: u32, y: u32, tex: u8| {
            [(x & 255) as u8, (y & 255) as u8, ((x >> 8) | ((y >> 8) << 4)) as u8, (tex << 4) | (level as u8 + 1)]
        };
        let buf = [px(2, 300, 4000, 1), px(2, 300, 4000, 1), px(0, 1, 1, 0), [0; 4]].concat();
        let f = decode_feedback(&buf, 1);
        assert_eq!(f.len(), 1);
        assert_eq!(f[&addr(2, 300, 4000)].pixels, 2);
        assert_eq!(pages(&decode_feedback(&buf, 0)), BTreeSet::from([addr(0, 1, 1)]));
    }

    #[test]
    fn inverse_of_a_view_projection() {
        let m = mul(&perspective(1.0, 1.5, 0.5, 100.0), &look_at([1.0, 2.0, 3.0], [4.0, -1.0, 0.0], [0.0, 0.0, 1.0]));
        let i = mul(&m, &invert(&m).unwrap());
        for (r, row) in i.iter().enumerate() {
            for (c, v) in row.iter().enumerate() {
                assert!((v - (r == c) as u8 as f64).abs() < 1e-9, "{i:?}");
            }
        }
        assert!(invert(&[[0.0; 4]; 4]).is_none());
    }
}
