//! Renders the cascade demos (or one of them) to PNG files for looking at:
//! `cargo run -p vtex-synth --release --example cascade_render -- OUT_DIR [LEVEL X Y SIZE] [NAME_FILTER]`.

use vtex_synth::models::{cascade, load};
use vtex_synth::texture::{render_image, Region};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let dir = args.first().cloned().unwrap_or_else(|| "cascade-demos".into());
    let num = |i: usize, d: i64| args.get(i).and_then(|s| s.parse().ok()).unwrap_or(d);
    let (level, x, y, size) = (num(1, 0) as u32, num(2, 0), num(3, 0), num(4, 512) as u32);
    let filter = args.get(5).cloned().unwrap_or_default();
    std::fs::create_dir_all(&dir).unwrap();
    for b in cascade::demos() {
        if !b.manifest.name.contains(&filter) {
            continue;
        }
        let tex = load(&b).unwrap();
        let t = std::time::Instant::now();
        let img = render_image(tex.as_ref(), &Region::new(level, x, y, size, size)).unwrap();
        let file = format!("{dir}/{}-L{level}.png", b.manifest.name.split(' ').nth(1).unwrap_or("x"));
        std::fs::write(&file, img.to_png()).unwrap();
        println!("{file}: {:?} ({} bytes encoding) {}", t.elapsed(), b.to_bytes().len(), b.manifest.params);
    }
}
