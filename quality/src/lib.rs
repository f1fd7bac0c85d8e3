//! vtex-quality: network-free texture metrics that every vtex model is judged with.
//!
//! Each metric compares a synthesized output with the sample it was made from, or inspects the
//! output alone, without any learned model or network:
//!
//! * [`repetition`] — long-range repetition: the largest normalised autocorrelation of the
//!   luminance at lags beyond the sample size (a plain tiling scores 1, white noise 0).
//! * [`seam`] — seam ratio: mean gradient magnitude on the places where a model joins copies
//!   of its sample, over the mean elsewhere (invisible joins score 1).
//! * [`contrast`] — contrast ratio: σ of the output's luminance over σ of the sample's.
//! * [`histogram`] — per-channel 1-D Wasserstein (W1) distance between colour histograms.
//! * [`patch_sw`] — sliced-Wasserstein distance between patch distributions at several
//!   pyramid scales.
//! * [`lattice`] — lattice share: how many pixels copy a sample pixel congruent to their own
//!   position modulo 2^j (a collage of a few aligned translations scores 1, chance 1/4^j).
//! * [`mip`] — PSNR of served coarse levels against the exact box chain, point sampling beside.
//!
//! [`wei_levoy_2000`] is a baseline to measure against, not a metric: the sequential synthesis
//! that order-independent synthesis was compared with.
//!
//! [`report`] gathers them for one output; [`gimp_pattern`] and [`sample`] read and prepare the
//! real samples the `quality-report` binary judges the models on.
//!
//! All metrics ignore alpha and work on sRGB-coded byte values as stored (no linearisation):
//! they judge what is served.

#![forbid(unsafe_code)]

pub mod contrast;
pub mod gimp_pattern;
pub mod histogram;
pub mod lattice;
pub mod luma;
pub mod mip;
pub mod patch_sw;
pub mod repetition;
pub mod report;
pub mod sample;
pub mod seam;
pub mod wei_levoy_2000;

pub use vtex_synth::{Error, Result, Rgba8Image};

#[cfg(test)]
pub(crate) mod test_images;
