//! Renders the demos; with `LCM_PNG_DIR` set, writes them as PNG files to look at.
//! `LCM_PNG_DIR=/tmp/lcm cargo test -p vtex-synth --test models lcm_pictures::`

use vtex_synth::models::lcm::demos;
use vtex_synth::texture::render_image;
use vtex_synth::{mip, Region, Texture};

#[test]
fn demos_render_with_contrast() {
    let dir = std::env::var("LCM_PNG_DIR").ok();
    for (name, p) in demos::all_params() {
        let tex = vtex_synth::models::lcm::load(&demos::make(name, &p).unwrap()).unwrap();
        let file = name.to_lowercase().replace([' ', '(', ')'], "_");
        for (level, size) in [(0u32, 768u32), (2, 512), (5, 256)] {
            let img = render_image(&tex, &Region::new(level, 0, 0, size, size)).unwrap();
            let mean = mip::mean_rgba(&img);
            let spread =
                img.data.chunks_exact(4).map(|p| (p[0] as f64 - mean[0]).abs()).sum::<f64>() / (size * size) as f64;
            if level == 0 {
                assert!(spread > 3.0, "{name} is flat (mean abs deviation {spread})");
            }
            if let Some(d) = &dir {
                std::fs::create_dir_all(d).unwrap();
                std::fs::write(format!("{d}/{file}_L{level}.png"), img.to_png()).unwrap();
            }
        }
        // The whole texture at the first level that fits in 512 px.
        let level = (0..40).find(|l| tex.width().max(tex.height()) >> l <= 512).unwrap();
        let (w, h) = vtex_synth::texture::level_size(tex.width(), tex.height(), level);
        let whole = render_image(&tex, &Region::new(level, 0, 0, w as u32, h as u32)).unwrap();
        if let Some(d) = &dir {
            std::fs::write(format!("{d}/{file}_whole_L{level}.png"), whole.to_png()).unwrap();
        }
        eprintln!("{name}: period {:?}, size {}×{}", tex.period(), tex.width(), tex.height());
    }
}
