//! Long-range repetition of the large `lcm` demos. A layer whose LCM does not cover the
//! texture tiles it; beyond the largest such tiling period, only layers lining up again could
//! make the texture repeat, and the large layer, which must not tile (paper §5), prevents it.
//! Where no layer tiles, no lag beyond one element may repeat.

use vtex_quality::repetition::Autocorrelation;
use vtex_synth::models::lcm::{self, demos};
use vtex_synth::texture::{level_size, render_image};
use vtex_synth::{Region, Texture};

/// Demos this small are shown whole at level 0; the brick walls tile two periods on purpose.
const LARGE: u64 = 4096;

#[test]
fn large_demos_do_not_repeat_beyond_their_largest_tiling_layer_period() {
    let mut report = Vec::new();
    for (name, p) in demos::all_params() {
        let t = lcm::load(&demos::make(name, &p).unwrap()).unwrap();
        if t.width().min(t.height()) < LARGE {
            continue;
        }
        let periods: Vec<(u64, u64)> = t.layer_periods().into_iter().map(|(_, p)| p).collect();
        // Layer 0, the largest elements, covers the whole texture.
        assert_eq!(periods[0], (t.width(), t.height()), "{name}: {periods:?}");
        // Beyond the largest period of a tiling layer; where none tiles, beyond one element.
        let element = 1u64 << (p.element.as_ref().unwrap().k + p.magnify);
        let tiling = |size: u64, axis: fn(&(u64, u64)) -> u64| {
            periods.iter().map(axis).filter(|&p| p < size).max().unwrap_or(element)
        };
        let largest = (tiling(t.width(), |p| p.0), tiling(t.height(), |p| p.1));
        // The whole texture at the first level that fits in 2048 px.
        let level = (0..)
            .find(|&l| {
                let (w, h) = level_size(t.width(), t.height(), l);
                w.max(h) <= 2048
            })
            .unwrap();
        let (w, h) = level_size(t.width(), t.height(), level);
        let img = render_image(&t, &Region::new(level, 0, 0, w as u32, h as u32)).unwrap();
        let beyond = ((largest.0 >> level) as u32, (largest.1 >> level) as u32);
        let r = Autocorrelation::new(&img).unwrap().max_outside(beyond.0, beyond.1).unwrap();
        println!(
            "{name}: {}×{}, layer periods {periods:?}; level {level}, lags beyond {beyond:?}: {r:?}",
            t.width(),
            t.height()
        );
        report.push((name, r));
    }
    assert!(report.len() >= 2, "{report:?}");
    for (name, r) in report {
        assert!(r.value < 0.2, "{name}: r = {:.3} at ({}, {}) px of its level", r.value, r.dx, r.dy);
    }
}
