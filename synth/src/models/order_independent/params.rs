//! The parameters of an order-independent texture, as given to `create` and stored in the
//! manifest (`generation0`, when not given, is derived: kept in the manifest's `derived`), and
//! their validation against the sample's size.
//!
//! ```json
//! {"seed": 7, "width": 100000, "height": 100000, "levels": 4, "generations": 5,
//!  "neighbourhood": {"same": "circle5", "lower": "square3"}, "search": "kcoherence", "k": 2,
//!  "k_exclusion": 2, "kappa": 100, "jitter": 1, "subpasses": 4,
//!  "mip": {"exact_levels": 0, "lookahead": 1, "noise_levels": 3}, "mip_generations": [1, 1, 2]}
//! ```

use crate::{Error, Result};
use serde::{Deserialize, Serialize};

/// Largest served extent per side.
pub const MAX_EXTENT: u64 = 1 << 40;
/// Largest sample side: an exemplar index must fit in a u16.
pub const MAX_SAMPLE_SIDE: u32 = 256;
/// Largest sample the exhaustive search scans for every entry (its tile cost).
pub const MAX_EXHAUSTIVE_PIXELS: u64 = 128 * 128;
pub const MAX_LEVELS: u8 = 8;
pub const MAX_GENERATIONS: u8 = 6;
pub const MAX_COARSEST_GENERATIONS: u8 = 3;
pub const MAX_K: u8 = 8;
pub const MAX_K_EXCLUSION: u8 = 16;
pub const MAX_JITTER: u8 = 4;
pub const MAX_KAPPA: u16 = 1000;
pub const MAX_BALANCE: u8 = 4;
pub const MAX_EXACT_LEVELS: u8 = 2;
pub const MAX_NOISE_LEVELS: u8 = 4;

/// Where the texture is defined.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(rename_all = "lowercase")]
pub enum DomainSpec {
    /// The unbounded plane; `width × height` is only the extent served.
    #[default]
    Plane,
    /// Periodic with `width × height`, which must be multiples of 2^(levels − 1).
    Torus,
}

/// Taps read at the entry's own level, from the previous generation (centre excluded).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(rename_all = "lowercase")]
pub enum SameShape {
    /// The paper's "circular 5×5" (Fig. 7): 20 taps.
    #[default]
    Circle5,
    /// The 5×5 square: 24 taps.
    Square5,
    /// The 3×3 square: 8 taps.
    Square3,
}

/// Taps read around the parent at the next coarser level, latest generation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(rename_all = "lowercase")]
pub enum LowerShape {
    #[default]
    Square3,
    Square5,
}

/// The neighbourhood compared when searching (paper: "circular 5×5 with 2 levels").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct Neighbourhood {
    #[serde(default)]
    pub same: SameShape,
    #[serde(default)]
    pub lower: LowerShape,
}

/// How an entry's best exemplar pixel is found.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(rename_all = "lowercase")]
pub enum Search {
    /// Every valid exemplar pixel (the paper's Table 1): the reference, slow.
    Exhaustive,
    /// k-coherence candidates (Tong et al. 2002): the served default.
    #[default]
    Kcoherence,
}

/// How generation 0 of a level above the coarsest is made.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(rename_all = "lowercase")]
pub enum Generation0 {
    /// The parent's exemplar coordinate, doubled, plus the pixel's parity (Lefebvre–Hoppe 2005).
    Upsample,
    /// Exhaustive search on the coarser level's part of the neighbourhood (the paper).
    Search,
}

/// What the levels of the search compare against.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(rename_all = "lowercase")]
pub enum ExemplarLevels {
    /// A Gaussian pyramid: level s is the sample subsampled 2^(K−1−s) times, and a coordinate
    /// indexes its own level (Wei & Levoy).
    Pyramid,
    /// A Gaussian stack: every level at the sample's resolution, blurred as the pyramid's,
    /// coordinates in the sample's own pixels at every level, and the taps of level s spaced
    /// h_s = 2^(K−1−s) apart (Lefebvre & Hoppe 2005). An upsampled copy may start at any
    /// pixel, so the output sits on no lattice of the sample. k-coherence only.
    Stack,
}

/// How coarse vtex levels are made (see `prefilter`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct MipSpec {
    /// Levels 1..=exact_levels are rendered at level 0 and box-filtered (4^level tiles each).
    #[serde(default)]
    pub exact_levels: u8,
    /// 1: vtex level j is coloured from synthesis level fin − (j − 1) and box-filtered once.
    #[serde(default = "one")]
    pub lookahead: u8,
    /// Levels beyond the pyramid that average the coloured noise exactly.
    #[serde(default = "three")]
    pub noise_levels: u8,
}

impl Default for MipSpec {
    fn default() -> Self {
        MipSpec { exact_levels: 0, lookahead: 1, noise_levels: 3 }
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct Params {
    /// Noise seed: the whole texture is a function of it and the sample.
    pub seed: u64,
    /// Served extent at vtex level 0.
    #[serde(default = "default_extent")]
    pub width: u64,
    #[serde(default = "default_extent")]
    pub height: u64,
    #[serde(default)]
    pub domain: DomainSpec,
    /// K, synthesis levels (paper: 4).
    #[serde(default = "four")]
    pub levels: u8,
    /// Generations of every level but the coarsest (paper: 3). Unset: 3 for `exhaustive`, 5 for
    /// `kcoherence`, whose four subpasses then correct every pixel once after the upsampling,
    /// one parity class at a time.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub generations: Option<u8>,
    /// Generations of the coarsest level; its generation 0 is the noise (paper, Fig. 7: 1).
    #[serde(default = "one")]
    pub coarsest_generations: u8,
    #[serde(default)]
    pub neighbourhood: Neighbourhood,
    #[serde(default)]
    pub search: Search,
    /// k-coherence set size, the pixel itself included: with 2, each neighbour also offers the
    /// pixel most like its continuation elsewhere in the sample, which lets a patch end.
    #[serde(default = "two")]
    pub k: u8,
    /// Chebyshev radius around a pixel from which its k-coherence set takes no other pixel, so
    /// that the alternative is another place of the sample, not the pixel next door.
    #[serde(default = "two")]
    pub k_exclusion: u8,
    /// κ in percent (Lefebvre & Hoppe 2005's coherence factor): a k-coherence candidate that is
    /// not a neighbour's coherent continuation must match (100 + κ)/100 times better to be
    /// chosen, so jumps happen where the coherent patch really fits worse. Unset when creating:
    /// [`DEFAULT_KAPPA`]; a stored encoding without it has 0 (plain SSD).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kappa: Option<u16>,
    /// Radius r of the hashed jitter added to every upsampled coordinate (generation 0 of each
    /// level above the coarsest): offsets uniform over −r..=r−1 on each axis, 2r values, so the
    /// finest level alone spreads a pixel's source over every residue mod 2 (and mod 4 for
    /// r ≥ 2). Unset when creating: [`DEFAULT_JITTER`]; a stored encoding without it has none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub jitter: Option<u8>,
    /// Unset when creating: `upsample` for `kcoherence`, `search` for `exhaustive`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub generation0: Option<Generation0>,
    /// Histogram balance, an exponent in halves (0..=4; 0 off): a k-coherence candidate's
    /// weighted SSD is also scaled by (used ⁄ fair)^(balance/2) of its luma band at its level,
    /// measured once at load on a pilot window of that level synthesised without it (Kopf et
    /// al. 2007's histogram weighting made static, so every entry stays a function of the
    /// encoding alone). Tones the SSD search over-uses then cost more, and the sample's extremes
    /// come back. Unset when creating: [`DEFAULT_BALANCE`] for `kcoherence`; a stored encoding
    /// without it has none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub balance: Option<u8>,
    /// Unset when creating: a stack for `kcoherence` with `upsample` generation 0, a pyramid
    /// otherwise; a stored encoding without it has a pyramid. A stack compares only same-level
    /// taps (its coordinates carry the coarser levels), so `neighbourhood.lower` is unused.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exemplar: Option<ExemplarLevels>,
    /// 1, or 4: generation m updates one parity class of pixels, `(m − 1) mod 4` (Lefebvre &
    /// Hoppe 2005's subpasses: each class reads its neighbours' corrected values). Unset: 1 for
    /// `exhaustive` (the paper), 4 for `kcoherence`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub subpasses: Option<u8>,
    /// The sample tiles seamlessly: its neighbourhoods wrap and every pixel is a candidate.
    #[serde(default)]
    pub exemplar_wrap: bool,
    #[serde(default)]
    pub mip: MipSpec,
    /// Per vtex level 1, 2, …: the generation of the synthesis level it reads (see `mip`),
    /// capped at that level's latest; levels past the list read the latest. An earlier
    /// generation skips the last subpasses, the dearest part of a coarse tile. Unset when
    /// creating: [`DEFAULT_MIP_GENERATIONS`] with four subpasses; a stored encoding without it
    /// reads the latest everywhere.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mip_generations: Option<Vec<u8>>,
}

fn default_extent() -> u64 {
    100_000
}
fn one() -> u8 {
    1
}
fn two() -> u8 {
    2
}
fn three() -> u8 {
    3
}
fn four() -> u8 {
    4
}

/// The jitter radius, κ and histogram balance `create` fills in when none is given.
pub const DEFAULT_JITTER: u8 = 1;
pub const DEFAULT_KAPPA: u16 = 100;
pub const DEFAULT_BALANCE: u8 = 1;
/// The generations vtex levels 1, 2 and 3 read when `create` is given none and the synthesis
/// has four subpasses: the fewest subpasses with which each level still keeps the model's mip
/// guarantee on the demos (`docs/models/order-independent.md`, levels).
pub const DEFAULT_MIP_GENERATIONS: [u8; 3] = [0, 1, 2];
/// The longest `mip_generations` list.
pub const MAX_MIP_GENERATIONS: usize = 8;

impl Params {
    /// Generations of every level but the coarsest.
    pub fn generations(&self) -> u8 {
        self.generations.unwrap_or(match self.search {
            Search::Exhaustive => 3,
            Search::Kcoherence => 5,
        })
    }

    /// Subpasses: 1 or 4.
    pub fn subpasses(&self) -> u8 {
        self.subpasses.unwrap_or(match self.search {
            Search::Exhaustive => 1,
            Search::Kcoherence => 4,
        })
    }

    /// The jitter radius (0 when the encoding has none).
    pub fn jitter(&self) -> u8 {
        self.jitter.unwrap_or(0)
    }

    /// The histogram balance exponent in halves (0 when the encoding has none).
    pub fn balance(&self) -> u8 {
        self.balance.unwrap_or(0)
    }

    /// The exemplar's levels (a pyramid when the encoding does not say).
    pub fn exemplar(&self) -> ExemplarLevels {
        self.exemplar.unwrap_or(ExemplarLevels::Pyramid)
    }

    /// κ in percent (0 when the encoding has none).
    pub fn kappa(&self) -> u16 {
        self.kappa.unwrap_or(0)
    }

    /// The parameters as stored: every default that depends on when the encoding was made
    /// filled in, so a later change of default never changes a stored texture.
    pub fn filled(mut self) -> Params {
        self.generation0 = Some(self.generation0());
        self.generations = Some(self.generations());
        self.subpasses = Some(self.subpasses());
        self.jitter = Some(self.jitter.unwrap_or(DEFAULT_JITTER));
        self.kappa = Some(self.kappa.unwrap_or(DEFAULT_KAPPA));
        let kcoherence = self.search == Search::Kcoherence;
        let upsampled = kcoherence && self.generation0() == Generation0::Upsample;
        let exemplar = if upsampled { ExemplarLevels::Stack } else { ExemplarLevels::Pyramid };
        self.exemplar = Some(self.exemplar.unwrap_or(exemplar));
        self.balance = Some(self.balance.unwrap_or(if kcoherence { DEFAULT_BALANCE } else { 0 }));
        if self.mip_generations.is_none() && self.subpasses() == 4 {
            self.mip_generations = Some(DEFAULT_MIP_GENERATIONS.to_vec());
        }
        self
    }

    /// The generation vtex level `l` ≥ 1 reads of a synthesis level whose latest is `last`.
    pub fn mip_generation(&self, l: u32, last: u8) -> u8 {
        let listed = self.mip_generations.as_ref().and_then(|g| g.get(l as usize - 1).copied());
        listed.map_or(last, |m| m.min(last))
    }

    /// `generation0`, or the default for the search mode.
    pub fn generation0(&self) -> Generation0 {
        self.generation0.unwrap_or(match self.search {
            Search::Exhaustive => Generation0::Search,
            Search::Kcoherence => Generation0::Upsample,
        })
    }

    /// Every check that needs only the parameters and the sample's size.
    pub fn validate(&self, sample_w: u32, sample_h: u32) -> Result<()> {
        for (name, v) in [("width", self.width), ("height", self.height)] {
            if !(1..=MAX_EXTENT).contains(&v) {
                return Err(Error::param(name, format!("{v}: must be 1..=2^40")));
            }
        }
        let range = |name: &str, v: u8, lo: u8, hi: u8| {
            if (lo..=hi).contains(&v) {
                Ok(())
            } else {
                Err(Error::param(name, format!("{v}: must be {lo}..={hi}")))
            }
        };
        range("levels", self.levels, 2, MAX_LEVELS)?;
        range("generations", self.generations(), 1, MAX_GENERATIONS)?;
        range("coarsest_generations", self.coarsest_generations, 1, MAX_COARSEST_GENERATIONS)?;
        range("k", self.k, 1, MAX_K)?;
        range("k_exclusion", self.k_exclusion, 0, MAX_K_EXCLUSION)?;
        range("jitter", self.jitter(), 0, MAX_JITTER)?;
        range("balance", self.balance(), 0, MAX_BALANCE)?;
        if self.kappa() > MAX_KAPPA {
            return Err(Error::param("kappa", format!("{}: must be 0..={MAX_KAPPA}", self.kappa())));
        }
        range("mip.exact_levels", self.mip.exact_levels, 0, MAX_EXACT_LEVELS)?;
        range("mip.lookahead", self.mip.lookahead, 0, 1)?;
        range("mip.noise_levels", self.mip.noise_levels, 0, MAX_NOISE_LEVELS)?;
        if let Some(g) = &self.mip_generations {
            if g.len() > MAX_MIP_GENERATIONS {
                return Err(Error::param(
                    "mip_generations",
                    format!("{} entries: at most {MAX_MIP_GENERATIONS}", g.len()),
                ));
            }
            for &m in g {
                range("mip_generations", m, 0, MAX_GENERATIONS - 1)?;
            }
        }
        if self.subpasses() != 1 && self.subpasses() != 4 {
            return Err(Error::param("subpasses", format!("{}: must be 1 or 4", self.subpasses())));
        }
        if self.exemplar() == ExemplarLevels::Stack
            && (self.search != Search::Kcoherence || self.generation0() != Generation0::Upsample)
        {
            return Err(Error::param("exemplar", "a stack needs `kcoherence` search and `upsample` generation 0"));
        }
        if self.balance() > 0 && self.search != Search::Kcoherence {
            return Err(Error::param("balance", "weights k-coherence candidates: needs `kcoherence` search"));
        }
        let unit = 1u64 << (self.levels - 1);
        if self.domain == DomainSpec::Torus && (self.width % unit != 0 || self.height % unit != 0) {
            return Err(Error::param(
                "domain",
                format!("a torus needs width and height divisible by 2^(levels − 1) = {unit}"),
            ));
        }
        if sample_w > MAX_SAMPLE_SIDE || sample_h > MAX_SAMPLE_SIDE {
            return Err(Error::image(
                "sample",
                format!("{sample_w}×{sample_h}: each side at most {MAX_SAMPLE_SIDE} (indices are 16-bit)"),
            ));
        }
        let min = 4 * unit;
        if (sample_w as u64) < min || (sample_h as u64) < min {
            return Err(Error::param(
                "levels",
                format!(
                    "{} levels need a sample of at least {min}×{min} (the coarsest level ≥ 4×4); it is {sample_w}×{sample_h}",
                    self.levels
                ),
            ));
        }
        if sample_w as u64 % unit != 0 || sample_h as u64 % unit != 0 {
            return Err(Error::param(
                "levels",
                format!("{} levels need sample sides divisible by {unit}; it is {sample_w}×{sample_h}", self.levels),
            ));
        }
        if self.search == Search::Exhaustive && sample_w as u64 * sample_h as u64 > MAX_EXHAUSTIVE_PIXELS {
            return Err(Error::param(
                "search",
                format!(
                    "exhaustive search scans the whole sample per entry: at most 128×128, not {sample_w}×{sample_h}"
                ),
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn named(params: serde_json::Value, w: u32, h: u32) -> String {
        let p: Params = serde_json::from_value(params.clone()).unwrap();
        match p.validate(w, h) {
            Err(Error::Param { name, .. }) | Err(Error::Image { name, .. }) => name,
            other => panic!("{params} on {w}×{h}: {other:?}"),
        }
    }

    #[test]
    fn bad_parameters_are_refused_by_name() {
        assert!(serde_json::from_value::<Params>(json!({"seed": 1})).unwrap().validate(64, 64).is_ok());
        assert_eq!(named(json!({"seed": 1}), 16, 64), "levels"); // coarsest level 2×8
        assert_eq!(named(json!({"seed": 1, "levels": 3}), 34, 36), "levels"); // not a multiple of 4
        assert_eq!(named(json!({"seed": 1}), 512, 64), "sample");
        assert_eq!(named(json!({"seed": 1, "search": "exhaustive"}), 256, 128), "search");
        assert_eq!(named(json!({"seed": 1, "levels": 9}), 64, 64), "levels");
        assert_eq!(named(json!({"seed": 1, "generations": 0}), 64, 64), "generations");
        assert_eq!(named(json!({"seed": 1, "coarsest_generations": 4}), 64, 64), "coarsest_generations");
        assert_eq!(named(json!({"seed": 1, "k": 9}), 64, 64), "k");
        assert_eq!(named(json!({"seed": 1, "k_exclusion": 17}), 64, 64), "k_exclusion");
        assert_eq!(named(json!({"seed": 1, "subpasses": 2}), 64, 64), "subpasses");
        assert_eq!(named(json!({"seed": 1, "jitter": 5}), 64, 64), "jitter");
        assert_eq!(named(json!({"seed": 1, "balance": 5}), 64, 64), "balance");
        assert_eq!(named(json!({"seed": 1, "balance": 1, "search": "exhaustive"}), 64, 64), "balance");
        assert_eq!(named(json!({"seed": 1, "kappa": 1001}), 64, 64), "kappa");
        assert_eq!(named(json!({"seed": 1, "exemplar": "stack", "search": "exhaustive"}), 64, 64), "exemplar");
        assert_eq!(named(json!({"seed": 1, "exemplar": "stack", "generation0": "search"}), 64, 64), "exemplar");
        assert_eq!(named(json!({"seed": 1, "width": 0}), 64, 64), "width");
        assert_eq!(named(json!({"seed": 1, "height": 1u64 << 41}), 64, 64), "height");
        assert_eq!(named(json!({"seed": 1, "domain": "torus", "width": 1000, "height": 1004}), 64, 64), "domain");
        assert_eq!(named(json!({"seed": 1, "mip": {"lookahead": 2}}), 64, 64), "mip.lookahead");
        assert_eq!(named(json!({"seed": 1, "mip": {"noise_levels": 5}}), 64, 64), "mip.noise_levels");
        assert_eq!(named(json!({"seed": 1, "mip": {"exact_levels": 3}}), 64, 64), "mip.exact_levels");
        assert_eq!(named(json!({"seed": 1, "mip_generations": [1, 6]}), 64, 64), "mip_generations");
        assert_eq!(
            named(json!({"seed": 1, "mip_generations": [0, 0, 0, 0, 0, 0, 0, 0, 0]}), 64, 64),
            "mip_generations"
        );
    }
}
