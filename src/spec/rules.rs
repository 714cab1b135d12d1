//! The ranges of the spec's numbers and which integrators read them: one table, which the
//! validation reads (`check_numbers`) and from which the API's schema takes its `minimum`s
//! and `maximum`s (server/openapi.rs), so that the two cannot disagree.

use super::{SpecError, SpecForm};

/// Largest image side (pixels).
pub const MAX_IMAGE_SIDE: u32 = 16384;

/// Largest photon count per map (about 30 GB of photons at worst).
pub const MAX_PHOTONS: u64 = 1_000_000_000;

/// Most passes of a progressive render (a pass costs at least a photon trace and a camera
/// pass).
pub const MAX_ITERATIONS: u32 = 1_000_000;

/// What values a number may take.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Range {
    /// A whole number in min..=max.
    Int { min: u64, max: u64 },
    /// A number strictly between 0 and 1.
    OpenUnit,
    /// A finite number above 0.
    Positive,
    /// A finite number in lo..=hi.
    Span { lo: f64, hi: f64 },
}

/// Which integrators read a field.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scope {
    /// Every integrator, or the default integrator's settings (accepted by every
    /// integrator; ignored by those that do not read them).
    Any,
    /// Integrators that trace photon maps (photon, ppm) only: an error elsewhere (the
    /// default integrator, auto, reads none of them).
    PhotonMaps,
    /// Progressive integrators only: an error elsewhere.
    Progressive,
    /// Integrators that merge with a shrinking radius (ppm, vcm) only: an error elsewhere.
    Merging,
    /// ppm only (its final gathers): an error elsewhere.
    Ppm,
}

impl Scope {
    /// Whether `spec`'s integrator reads a field of this scope.
    pub fn read_by(self, spec: &super::RenderSpec) -> bool {
        match self {
            Scope::Any => true,
            Scope::PhotonMaps => spec.photon_mapping().is_some(),
            Scope::Progressive => spec.is_progressive(),
            Scope::Merging => spec.merge_radius().is_some(),
            Scope::Ppm => matches!(spec.integrator, super::Integrator::Ppm(_)),
        }
    }
}

#[derive(Debug)]
pub struct Rule {
    pub field: &'static str,
    pub scope: Scope,
    pub range: Range,
}

const fn rule(field: &'static str, scope: Scope, range: Range) -> Rule {
    Rule {
        field,
        scope,
        range,
    }
}

const fn int(min: u64, max: u64) -> Range {
    Range::Int { min, max }
}

/// Every number of the form, with its range and scope.
pub const RULES: &[Rule] = &[
    rule("width", Scope::Any, int(1, MAX_IMAGE_SIDE as u64)),
    rule("height", Scope::Any, int(1, MAX_IMAGE_SIDE as u64)),
    rule("photons", Scope::PhotonMaps, int(0, MAX_PHOTONS)),
    rule("caustic_photons", Scope::PhotonMaps, int(0, MAX_PHOTONS)),
    rule("k", Scope::PhotonMaps, int(1, 100_000)),
    rule("gather_rays", Scope::PhotonMaps, int(0, 65_536)),
    rule("shadow_rays", Scope::PhotonMaps, int(1, 256)),
    rule("spp", Scope::Any, int(1, 65_536)),
    rule("max_depth", Scope::Any, int(1, 1024)),
    rule(
        "iterations",
        Scope::Progressive,
        int(1, MAX_ITERATIONS as u64),
    ),
    rule("alpha", Scope::Merging, Range::OpenUnit),
    rule("radius", Scope::Merging, Range::Positive),
    rule(
        "gather_smoothing",
        Scope::Ppm,
        Range::Span { lo: 0.0, hi: 64.0 },
    ),
    rule("time_limit", Scope::Progressive, Range::Positive),
    rule("target_error", Scope::Progressive, Range::Positive),
    rule(
        "exposure",
        Scope::Any,
        Range::Span {
            lo: -64.0,
            hi: 64.0,
        },
    ),
];

/// The rule of a field, if it is a number.
pub fn rule_of(field: &str) -> Option<&'static Rule> {
    RULES.iter().find(|r| r.field == field)
}

/// The fields of the form that are not numbers and that only some integrators read.
const SCOPED_CHOICES: &[(&str, Scope)] = &[
    ("photon_store", Scope::PhotonMaps),
    ("aim_caustics", Scope::PhotonMaps),
];

/// Every field whose readers are scoped, with its scope: the numbers' rules and
/// [`SCOPED_CHOICES`].
pub fn scopes() -> impl Iterator<Item = (&'static str, Scope)> {
    let numbers = RULES.iter().map(|r| (r.field, r.scope));
    numbers.chain(SCOPED_CHOICES.iter().copied())
}

/// Which integrators read a field (its name as the form spells it, and its scope).
pub fn scope_of(field: &str) -> Option<(&'static str, Scope)> {
    scopes().find(|(f, _)| *f == field)
}

impl Range {
    /// Why `v` is out of this range, if it is.
    fn check(self, v: f64) -> Option<String> {
        match self {
            Range::Int { min, max } if !(v >= min as f64 && v <= max as f64) => Some(if min == 0 {
                format!("must be at most {max}, got {}", whole(v))
            } else {
                format!("must be in {min}..={max}, got {}", whole(v))
            }),
            Range::OpenUnit if !(v > 0.0 && v < 1.0) => {
                Some(format!("must be in (0, 1) (exclusive), got {v}"))
            }
            Range::Positive if !(v > 0.0 && v.is_finite()) => {
                Some(format!("must be a positive number, got {v}"))
            }
            Range::Span { lo, hi } if !(v >= lo && v <= hi) => {
                Some(format!("must be a finite number in {lo}..={hi}, got {v}"))
            }
            _ => None,
        }
    }
}

/// A whole number as written (the form's integers reach here as f64).
fn whole(v: f64) -> String {
    if v >= 0.0 {
        format!("{}", v as u64)
    } else {
        format!("{v}")
    }
}

/// Check every number the form gives against its rule.
pub fn check_numbers(f: &SpecForm) -> Result<(), SpecError> {
    for (field, v) in f.numbers() {
        let Some(v) = v else { continue };
        let rule = rule_of(field).expect("every number of the form has a rule");
        if let Some(message) = rule.range.check(v) {
            return Err(SpecError::new(rule.field, message));
        }
    }
    Ok(())
}

impl SpecForm {
    /// The form's numbers by name, as f64 (every integer the form takes is exact in f64 up
    /// to its range's maximum, and beyond it still compares as beyond).
    pub(super) fn numbers(&self) -> [(&'static str, Option<f64>); 16] {
        let u = |v: Option<u64>| v.map(|v| v as f64);
        let u32 = |v: Option<u32>| v.map(f64::from);
        [
            ("width", u32(self.width)),
            ("height", u32(self.height)),
            ("photons", u(self.photons)),
            ("caustic_photons", u(self.caustic_photons)),
            ("k", self.k.map(|k| k as f64)),
            ("gather_rays", u32(self.gather_rays)),
            ("shadow_rays", u32(self.shadow_rays)),
            ("spp", u32(self.spp)),
            ("max_depth", u32(self.max_depth)),
            ("iterations", u32(self.iterations)),
            ("alpha", self.alpha),
            ("radius", self.radius.map(f64::from)),
            ("gather_smoothing", self.gather_smoothing.map(f64::from)),
            ("time_limit", self.time_limit),
            ("target_error", self.target_error),
            ("exposure", self.exposure.map(f64::from)),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_rule_is_a_number_of_the_form_and_the_other_way_round() {
        let names: Vec<&str> = SpecForm::default()
            .numbers()
            .iter()
            .map(|(n, _)| *n)
            .collect();
        let rules: Vec<&str> = RULES.iter().map(|r| r.field).collect();
        assert_eq!(names, rules);
    }

    #[test]
    fn ranges_name_what_is_wrong() {
        let f = SpecForm {
            k: Some(0),
            ..SpecForm::default()
        };
        let e = check_numbers(&f).unwrap_err();
        assert_eq!(
            (e.field, e.message.as_str()),
            ("k", "must be in 1..=100000, got 0")
        );
        let f = SpecForm {
            alpha: Some(f64::NAN),
            ..SpecForm::default()
        };
        assert_eq!(check_numbers(&f).unwrap_err().field, "alpha");
        let f = SpecForm {
            photons: Some(u64::MAX),
            ..SpecForm::default()
        };
        let e = check_numbers(&f).unwrap_err();
        assert!(e.message.contains("at most 1000000000"), "{e}");
    }
}
