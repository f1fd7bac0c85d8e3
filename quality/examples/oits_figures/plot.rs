//! Line charts and labelled image grids drawn straight into an RGBA8 image, with a 3×5 pixel
//! font, so the figures need no font files or system libraries.

use vtex_synth::Rgba8Image;

pub const BLACK: [u8; 3] = [0, 0, 0];
pub const GREY: [u8; 3] = [200, 200, 200];
/// Distinct line colours, in order.
pub const PALETTE: [[u8; 3]; 10] = [
    [31, 119, 180],
    [214, 39, 40],
    [44, 160, 44],
    [255, 127, 14],
    [148, 103, 189],
    [140, 86, 75],
    [227, 119, 194],
    [127, 127, 127],
    [188, 189, 34],
    [23, 190, 207],
];

/// Glyph rows, 3 bits each, top row first.
fn glyph(c: char) -> [u8; 5] {
    match c.to_ascii_uppercase() {
        '0' => [7, 5, 5, 5, 7],
        '1' => [2, 6, 2, 2, 7],
        '2' => [7, 1, 7, 4, 7],
        '3' => [7, 1, 7, 1, 7],
        '4' => [5, 5, 7, 1, 1],
        '5' => [7, 4, 7, 1, 7],
        '6' => [7, 4, 7, 5, 7],
        '7' => [7, 1, 1, 1, 1],
        '8' => [7, 5, 7, 5, 7],
        '9' => [7, 5, 7, 1, 7],
        'A' => [2, 5, 7, 5, 5],
        'B' => [6, 5, 6, 5, 6],
        'C' => [3, 4, 4, 4, 3],
        'D' => [6, 5, 5, 5, 6],
        'E' => [7, 4, 6, 4, 7],
        'F' => [7, 4, 6, 4, 4],
        'G' => [3, 4, 5, 5, 3],
        'H' => [5, 5, 7, 5, 5],
        'I' => [7, 2, 2, 2, 7],
        'J' => [1, 1, 1, 5, 2],
        'K' => [5, 5, 6, 5, 5],
        'L' => [4, 4, 4, 4, 7],
        'M' => [5, 7, 7, 5, 5],
        'N' => [6, 5, 5, 5, 5],
        'O' => [2, 5, 5, 5, 2],
        'P' => [6, 5, 6, 4, 4],
        'Q' => [2, 5, 5, 6, 3],
        'R' => [6, 5, 6, 5, 5],
        'S' => [3, 4, 2, 1, 6],
        'T' => [7, 2, 2, 2, 2],
        'U' => [5, 5, 5, 5, 7],
        'V' => [5, 5, 5, 5, 2],
        'W' => [5, 5, 7, 7, 5],
        'X' => [5, 5, 2, 5, 5],
        'Y' => [5, 5, 2, 2, 2],
        'Z' => [7, 1, 2, 4, 7],
        '.' => [0, 0, 0, 0, 2],
        ',' => [0, 0, 0, 2, 4],
        ':' => [0, 2, 0, 2, 0],
        '%' => [5, 1, 2, 4, 5],
        '/' => [1, 1, 2, 4, 4],
        '-' => [0, 0, 7, 0, 0],
        '=' => [0, 7, 0, 7, 0],
        '(' => [2, 4, 4, 4, 2],
        ')' => [2, 1, 1, 1, 2],
        '|' => [2, 2, 2, 2, 2],
        _ => [0; 5],
    }
}

/// An image being drawn on.
pub struct Canvas {
    pub image: Rgba8Image,
}

impl Canvas {
    pub fn new(width: u32, height: u32) -> Self {
        let mut image = Rgba8Image::new(width, height);
        image.data.chunks_exact_mut(4).for_each(|p| p.copy_from_slice(&[255, 255, 255, 255]));
        Self { image }
    }

    pub fn set(&mut self, x: i64, y: i64, c: [u8; 3]) {
        if x >= 0 && y >= 0 && x < self.image.width as i64 && y < self.image.height as i64 {
            self.image.set_pixel(x as u32, y as u32, [c[0], c[1], c[2], 255]);
        }
    }

    pub fn rect(&mut self, x: i64, y: i64, w: i64, h: i64, c: [u8; 3]) {
        for yy in y..y + h {
            for xx in x..x + w {
                self.set(xx, yy, c);
            }
        }
    }

    /// A line `width` pixels thick.
    pub fn line(&mut self, (x0, y0): (f64, f64), (x1, y1): (f64, f64), width: i64, c: [u8; 3]) {
        let steps = (x1 - x0).abs().max((y1 - y0).abs()).ceil().max(1.0) as i64;
        for i in 0..=steps {
            let t = i as f64 / steps as f64;
            let (x, y) = ((x0 + t * (x1 - x0)).round() as i64, (y0 + t * (y1 - y0)).round() as i64);
            self.rect(x - width / 2, y - width / 2, width, width, c);
        }
    }

    /// Text with its top-left corner at (x, y), each font pixel `scale` pixels.
    pub fn text(&mut self, x: i64, y: i64, scale: i64, s: &str, c: [u8; 3]) {
        for (i, ch) in s.chars().enumerate() {
            for (row, bits) in glyph(ch).iter().enumerate() {
                for col in 0..3 {
                    if bits >> (2 - col) & 1 == 1 {
                        self.rect(x + (i as i64 * 4 + col) * scale, y + row as i64 * scale, scale, scale, c);
                    }
                }
            }
        }
    }

    pub fn text_width(s: &str, scale: i64) -> i64 {
        s.chars().count() as i64 * 4 * scale - scale
    }
}

/// A chart axis: linear or log₁₀/log₂-spaced, with labelled ticks.
pub struct Axis {
    pub label: String,
    pub min: f64,
    pub max: f64,
    pub log: bool,
    pub ticks: Vec<(f64, String)>,
}

impl Axis {
    fn position(&self, v: f64) -> f64 {
        let f = |v: f64| if self.log { v.ln() } else { v };
        (f(v) - f(self.min)) / (f(self.max) - f(self.min))
    }
}

pub struct Series {
    pub name: String,
    pub color: [u8; 3],
    pub points: Vec<(f64, f64)>,
}

const SCALE: i64 = 2;

/// A line chart with markers and a legend at the right.
pub fn chart(title: &str, x: &Axis, y: &Axis, series: &[Series], width: u32, height: u32) -> Rgba8Image {
    let mut c = Canvas::new(width, height);
    let legend_w = series.iter().map(|s| Canvas::text_width(&s.name, SCALE)).max().unwrap_or(0) + 40;
    let (left, top, right, bottom) = (70, 60, width as i64 - legend_w - 20, height as i64 - 60);
    let px = |v: f64| left as f64 + x.position(v) * (right - left) as f64;
    let py = |v: f64| bottom as f64 - y.position(v) * (bottom - top) as f64;
    c.text(8, 8, SCALE, title, BLACK);
    for (v, label) in &x.ticks {
        let p = px(*v);
        c.line((p, top as f64), (p, bottom as f64), 1, GREY);
        c.text(p as i64 - Canvas::text_width(label, SCALE) / 2, bottom + 8, SCALE, label, BLACK);
    }
    for (v, label) in &y.ticks {
        let p = py(*v);
        c.line((left as f64, p), (right as f64, p), 1, GREY);
        c.text(left - 8 - Canvas::text_width(label, SCALE), p as i64 - 5, SCALE, label, BLACK);
    }
    c.line((left as f64, top as f64), (left as f64, bottom as f64), 2, BLACK);
    c.line((left as f64, bottom as f64), (right as f64, bottom as f64), 2, BLACK);
    c.text((left + right) / 2 - Canvas::text_width(&x.label, SCALE) / 2, bottom + 30, SCALE, &x.label, BLACK);
    c.text(8, top - 20, SCALE, &y.label, BLACK);
    for (i, s) in series.iter().enumerate() {
        let inside = |&&(a, b): &&(f64, f64)| a >= x.min && a <= x.max && b >= y.min && b <= y.max;
        let points: Vec<(f64, f64)> = s.points.iter().filter(inside).map(|&(a, b)| (px(a), py(b))).collect();
        for w in points.windows(2) {
            c.line(w[0], w[1], 2, s.color);
        }
        if points.len() <= 64 {
            for &(a, b) in &points {
                c.rect(a as i64 - 3, b as i64 - 3, 7, 7, s.color);
            }
        }
        let ly = top + 10 + i as i64 * 22;
        c.rect(right + 20, ly, 14, 10, s.color);
        c.text(right + 40, ly, SCALE, &s.name, BLACK);
    }
    c.image
}

/// Ticks at the powers of two from `min` to `max`, labelled with `label`.
pub fn powers_of_two(min: u64, max: u64, label: impl Fn(u64) -> String) -> Vec<(f64, String)> {
    std::iter::successors(Some(min), |&v| Some(v * 2)).take_while(|&v| v <= max).map(|v| (v as f64, label(v))).collect()
}

/// Images side by side (or stacked), top-aligned, with `gap` white pixels between them.
pub fn beside(images: &[Rgba8Image], gap: u32, vertical: bool) -> Rgba8Image {
    let along = |i: &Rgba8Image| if vertical { i.height } else { i.width };
    let across = |i: &Rgba8Image| if vertical { i.width } else { i.height };
    let total = images.iter().map(along).sum::<u32>() + gap * images.len().saturating_sub(1) as u32;
    let thick = images.iter().map(across).max().unwrap_or(0);
    let mut c = if vertical { Canvas::new(thick, total) } else { Canvas::new(total, thick) };
    let mut at = 0;
    for i in images {
        if vertical {
            c.image.blit(i, 0, at);
        } else {
            c.image.blit(i, at, 0);
        }
        at += along(i) + gap;
    }
    c.image
}

/// `labels` written above `image`.
pub fn captioned(image: &Rgba8Image, label: &str) -> Rgba8Image {
    let mut c = Canvas::new(image.width.max(Canvas::text_width(label, SCALE) as u32 + 8), image.height + 18);
    c.text(2, 2, SCALE, label, BLACK);
    c.image.blit(image, 0, 18);
    c.image
}
