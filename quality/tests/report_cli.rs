//! The `quality-report` binary end to end on generated samples (no network, no packages): one
//! photo-like PNG and one GIMP pattern written by the test itself.

use std::process::Command;
use vtex_synth::samples;

/// A `.pat` file as GIMP writes it (RGB).
fn gimp_pat(name: &str, img: &vtex_synth::Rgba8Image) -> Vec<u8> {
    let mut out = Vec::new();
    for v in [24 + name.len() as u32 + 1, 1, img.width, img.height, 3] {
        out.extend(v.to_be_bytes());
    }
    out.extend(b"GPAT");
    out.extend(name.as_bytes());
    out.push(0);
    out.extend(img.data.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]));
    out
}

#[test]
fn writes_tables_and_side_by_side_pngs() {
    let dir = std::env::temp_dir().join(format!("vtex-quality-cli-{}", std::process::id()));
    let out = dir.join("out");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("cobbles.png"), samples::pebbles(300, 40, 3, false).to_png()).unwrap();
    std::fs::write(dir.join("lichen.pat"), gimp_pat("Lichen", &samples::lichen(64, 2))).unwrap();
    std::fs::write(dir.join("broken.pat"), b"GPAT").unwrap();
    let status = Command::new(env!("CARGO_BIN_EXE_quality-report"))
        .args([dir.join("cobbles.png"), dir.join("lichen.pat"), dir.join("broken.pat")])
        .args(["--size", "256", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(status.status.success(), "{}", String::from_utf8_lossy(&status.stderr));
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    for want in ["## cobbles", "## lichen", "| repetition (lag) | 1.000", "tiling + edge filter", "broken.pat"] {
        assert!(report.contains(want), "missing {want:?} in\n{report}");
    }
    for name in ["cobbles", "lichen"] {
        let png = std::fs::read(out.join(format!("{name}-side-by-side.png"))).unwrap();
        let img = vtex_synth::pixels::decode_png("side", &png).unwrap();
        assert_eq!((img.width, img.height), (256 + 16 + 256, 256));
        let sample =
            vtex_synth::pixels::decode_png("s", &std::fs::read(out.join(format!("{name}-sample.png"))).unwrap());
        // The photo is centre-cropped to 128 × 128; the pattern is used as it is.
        let side = if name == "cobbles" { 128 } else { 64 };
        assert_eq!(sample.map(|s| (s.width, s.height)).unwrap(), (side, side));
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn refuses_bad_usage_with_a_message() {
    let out = Command::new(env!("CARGO_BIN_EXE_quality-report")).arg("x.png").output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--out"));
}
