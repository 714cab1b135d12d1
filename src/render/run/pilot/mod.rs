//! `auto`'s pilot between final gathering and connections on a room without mirror or
//! glass. In an open box lit from its ceiling `ppm` with final gathering reached Mitsuba's
//! error 1.5-5x sooner than `pt`, and `pt` 15-20% sooner than `bdpt` (docs/performance.md,
//! "2026-12-04, late night"; docs/performance-history.md, "auto's pilot"); where the camera
//! sees mostly light that came off a small bright patch (a skewed quad light facing a wall
//! at a few centimetres, which shadow rays sample by area) a gather ray finds the patch as
//! rarely as a camera path's bounce does, and `bdpt`'s connections may win. The scene's
//! facts do not tell the two apart (the share of seen surfaces lit directly was tried: 0.70
//! in cornell, 0.74 and 0.89 in two rooms where `bdpt` won against `pt`), the variance of
//! a small render does.
//!
//! The pilot renders the image at about 48x48 pixels, twice per integrator under two seeds
//! of its own, [`FIRST_LOOK`] or [`PILOT_PASSES`] passes each (`renders.rs`), and compares
//! per-pass variances (the squared difference between a pair, relative as `relmse` weighs
//! it), in two stages:
//!
//! 1. `pt` against `bdpt`: where `pt`'s variance is within [`BOUNCE_FINDS_THE_LIGHT`]
//!    times `bdpt`'s, a camera path's bounce finds the light,
//!    and so do gather rays: gathering, without more pilot (cornell, knot);
//! 2. otherwise `auto`'s gathering itself (its photons scaled to the pilot's pixels, so
//!    that a density estimate spans as many pixels as in the render; about as long again)
//!    against `bdpt`: `bdpt` when gathering's variance times [`GATHERING_PASS_COST`] is
//!    the larger. A point light's hot spot (cornell_spheres) makes `pt` poor but not
//!    gathering, whose shadow rays reach the light from where its gather rays land; a
//!    light that shadow rays sample poorly from there (a parallelogram a few centimetres
//!    from the wall it faces) makes both poor.
//!
//! Stage 1 looks first after [`FIRST_LOOK`] passes and decides there where its ratio lies
//! clearly on one side of its threshold ([`CLEAR_MARGIN`]); otherwise its renders continue
//! from their states to [`PILOT_PASSES`] (the same bytes as one render of that many) and it
//! decides as it did before the first look was added. Stage 2 runs as many passes as stage
//! 1 did and, after 4, looks first the same way. Clear after 4: an open box under a
//! ceiling light, a washed wall, a room behind a partition; the pilot took 30-55% less time
//! there, with the same choices. Where a ratio is near its threshold (cornell_spheres' stage
//! 2, some seeds of cornell and knot) the pilot runs as long as before. The early decisions
//! are empirical: the margins hold the ratios measured (docs/performance-history.md, "the
//! pilot's first look"), not a bound.
//!
//! Under a short time limit alone (`auto.rs`, `SHORT_LIMIT`) every look is the last
//! ([`Looks::of`]): a stage decides at its first look by the side of its threshold its
//! ratio lies on. Near a threshold the two integrators reach an error about equally soon,
//! so four more passes there buy a choice worth little, at a price the short budget pays
//! in full (on a room lit by two sphere lights both stages continued: a quarter of a 1-s
//! budget). There stage 1 looks after [`SHORT_FIRST_LOOK`] passes, and stage 2 after
//! [`FIRST_LOOK`] still (`bdpt`'s pair continued from stage 1's states): stage 1's ratio
//! after 2 passes lay on the side of its threshold it lay on after 4 in every room measured,
//! stage 2's fell to 0.64-0.87 of it, which flipped the rooms near its threshold (a point
//! light's hot spot) to `bdpt` (docs/performance-history.md, "the pilot's first look in two
//! passes").
//!
//! Before 2026-12-05 the first stage decided alone, and chose `bdpt` on cornell_spheres,
//! where gathering is 1.3-3x sooner. A function of the scene and the spec alone (the
//! pilot's bytes do not depend on the thread count or the clock), so the choice is the
//! same on every run.

mod renders;

use super::auto::{GatherShape, short_limit};
use crate::render::control::Control;
use crate::render::outcome::RenderError;
use crate::render::scene::Scene;
use crate::spec::{Integrator, Passes, RenderSpec};
use renders::{Pair, Renders, variances};

/// Below how many times `bdpt`'s per-pass variance `pt`'s lies where a camera path's bounce
/// finds the light, so that gathering needs no pilot of its own: a `bdpt` pass's cost in
/// `pt` passes (1.5-1.8), times the least of how much sooner gathering reached Mitsuba's
/// error than `pt` (1.7). pt/bdpt read 1.5-2.0 on cornell and knot, 4.4-6.4 where a bright
/// patch lights the room, with 16 passes and the old weight (docs/performance-history.md,
/// "auto's pilot"); 1.7-2.4 and 6.2-37 with 8 passes weighed by `bdpt`'s mean.
const BOUNCE_FINDS_THE_LIGHT: f64 = 1.8 * 1.7;

/// About how many times a `bdpt` pass's time a pass of `auto`'s gathering takes (one
/// sample and its gather rays a pixel, and the pass's photons): 1.64 on cornell_spheres,
/// 2.15 on cornell, 2.08 on tests/bidir.rs's `WALL_WASH` at 256x256, since its density
/// estimates search a hashed grid (docs/performance-history.md, "ppm's range search in a
/// hashed grid").
const GATHERING_PASS_COST: f64 = 2.0;

/// Pixels of a pilot image (its aspect the camera's).
const PILOT_PIXELS: f64 = 2304.0;

/// The most passes a pilot render runs. With the pixels weighed by `bdpt`'s mean
/// (`renders.rs`, `pass_variance`) 8 tell the rooms apart as 16 did, seeds 1-5: the first
/// stage's pt/bdpt 1.7-2.4 on cornell and knot against 6.2-6.6 on cornell_spheres and
/// 23-37 where a light
/// washes a wall; the second stage's bdpt/gathering over the pass cost 1.9-2.1 on
/// cornell_spheres, 0.5-0.6 and under 0.03 on a washed wall lit by a rectangle and by a
/// parallelogram (docs/performance-history.md, "the pilot weighed by bdpt's mean").
const PILOT_PASSES: u32 = 8;

/// Passes after which the pilot first looks: where a stage's ratio lies clearly on one side
/// of its threshold it decides there, else its renders continue (from their states: the
/// same bytes) to [`PILOT_PASSES`] and it decides as before.
const FIRST_LOOK: u32 = 4;

/// Passes after which stage 1 looks, once, under a short time limit alone: half of
/// [`FIRST_LOOK`], which halves the pilot where stage 1 decides (cornell 0.053 -> 0.029 s,
/// knot 0.091 -> 0.054 s of a 1-s budget on a 2-core host). Its ratio read 0.96-1.22 times
/// its value after 4 passes there, below the threshold where that was (2.5 at most against
/// 3.06), and above it where that was (docs/performance-history.md, "the pilot's first look
/// in two passes").
const SHORT_FIRST_LOOK: u32 = 2;

/// After how many passes a pilot stage first looks, and how many it may run at most.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Looks {
    first: u32,
    last: u32,
}

impl Looks {
    /// Stage 1's looks for a render stopped by `passes`: [`FIRST_LOOK`], and
    /// [`PILOT_PASSES`] where that was not clear, except under a short time limit alone,
    /// where one look after [`SHORT_FIRST_LOOK`] passes decides by the side of the threshold.
    fn of(passes: &Passes) -> Looks {
        if short_limit(passes) {
            return Looks {
                first: SHORT_FIRST_LOOK,
                last: SHORT_FIRST_LOOK,
            };
        }
        Looks {
            first: FIRST_LOOK,
            last: PILOT_PASSES,
        }
    }

    /// Stage 2's looks after stage 1 ran `passes`: its first after as many, but never
    /// fewer than [`FIRST_LOOK`] (its ratio drifts with fewer), and its last no sooner.
    fn stage_two(&self, passes: u32) -> Looks {
        let first = passes.max(FIRST_LOOK);
        Looks {
            first,
            last: self.last.max(first),
        }
    }

    /// Whether a first look's `ratio` decides the stage: it lies clearly on one side of its
    /// threshold (under `low` or over `high`), or no later look follows.
    fn decides(&self, ratio: f64, low: f64, high: f64) -> bool {
        self.first >= self.last || verdict(ratio, low, high).is_some()
    }
}

/// How far a ratio must lie from its threshold (times or over) for the first look to
/// decide. Seeds 1-5 at 256x256 (docs/performance-history.md, "the pilot's first look"):
/// stage 1's ratio after 4 passes lay within 1.25 times of its value after 8 where it was
/// near the threshold (cornell, knot, a room lit by two sphere lights), 1.6 times where it
/// was far (a washed wall, 21-48 against 23-37); stage 2's read 0.66-0.99 of it. Every
/// first look beyond 1.4 chose as the eighth pass did.
const CLEAR_MARGIN: f64 = 1.4;

/// Below what stage 2's first look (`bdpt`'s variance over gathering's times its pass cost)
/// takes `bdpt`: its ratio after 4 passes read 0.66-0.99 of its value after 8, so a read
/// under 1 / [`CLEAR_MARGIN`] could still be gathering's after 8; under 0.5 it could not at
/// that drift (the washed wall read 0.23-0.29).
const STAGE_TWO_BDPT_BELOW: f64 = 0.5;

/// How the second stage's gathering spends its rays, and so the render's where it ran:
/// where `pt`'s bounce finds the light poorly, more rays a camera sample.
const SECOND_STAGE_SHAPE: GatherShape = GatherShape::OnOneSample;

/// The fewest photons a pilot pass of gathering traces, however small the image.
const MIN_PILOT_PHOTONS: u64 = 1_000;

/// Whether `ratio` is clearly below (Some(false): under `low`) or above (Some(true): over
/// `high`) its threshold between them; None where it is close.
fn verdict(ratio: f64, low: f64, high: f64) -> Option<bool> {
    if ratio < low {
        Some(false)
    } else if ratio > high {
        Some(true)
    } else {
        None
    }
}

/// What the pilot found: each integrator's per-pass variance (relative, summed over the
/// pilot image's pixels and channels); gathering's only where `pt`'s bounce found the
/// light poorly.
#[derive(Clone, Copy, Debug)]
pub(super) struct Pilot {
    pub pt: f64,
    pub bdpt: f64,
    pub gathering: Option<f64>,
    /// The passes `pt`'s variance is over, and `bdpt`'s (and gathering's): [`FIRST_LOOK`]
    /// or [`PILOT_PASSES`] each, or under a short time limit [`SHORT_FIRST_LOOK`] and, where
    /// stage 2 ran, [`FIRST_LOOK`].
    pub passes: [u32; 2],
}

impl Pilot {
    /// Whether `bdpt` reaches a given error sooner than `ppm` with final gathering, by the
    /// pilot: variance times the cost of a pass.
    pub fn prefers_bdpt(&self) -> bool {
        self.gathering
            .is_some_and(|g| g * GATHERING_PASS_COST > self.bdpt)
    }

    /// How gathering should spend its rays: over more camera samples where a camera path's
    /// bounce found the light (the first stage decided alone), else as the second stage
    /// rendered it ([`SECOND_STAGE_SHAPE`]), the shape its variance vouches for.
    pub fn gather_shape(&self) -> GatherShape {
        match self.gathering {
            None => GatherShape::OverSamples,
            Some(_) => SECOND_STAGE_SHAPE,
        }
    }
}

/// The pilot of `spec` (its seed, depth and effect switches) on `scene` for a render stopped
/// by `passes`, cancelled with `control`: `pt` against `bdpt`, then, where `pt` did poorly,
/// gathering against `bdpt`.
pub(super) fn run_pilot(
    scene: &Scene,
    spec: &RenderSpec,
    passes: &Passes,
    control: &Control,
) -> Result<Pilot, RenderError> {
    pilot_looking(scene, spec, control, Looks::of(passes))
}

/// [`run_pilot`] with its `looks`.
fn pilot_looking(
    scene: &Scene,
    spec: &RenderSpec,
    control: &Control,
    looks: Looks,
) -> Result<Pilot, RenderError> {
    let renders = Renders::new(scene, spec, control);
    let (bdpt_pair, passes, pt, bdpt) = stage_one(&renders, looks)?;
    if pt <= BOUNCE_FINDS_THE_LIGHT * bdpt {
        return Ok(Pilot {
            pt,
            bdpt,
            gathering: None,
            passes: [passes; 2],
        });
    }
    let (gathering, bdpt, compared) = stage_two(&renders, bdpt_pair, looks.stage_two(passes))?;
    Ok(Pilot {
        pt,
        bdpt,
        gathering: Some(gathering),
        passes: [passes, compared],
    })
}

/// Stage 1, `pt` against `bdpt`: `bdpt`'s pair, the passes it ran, and the two variances.
fn stage_one(renders: &Renders, looks: Looks) -> Result<(Pair, u32, f64, f64), RenderError> {
    let both = |upto: u32, resume: Option<(Pair, Pair)>| {
        let (rb, rp) = resume.map_or((None, None), |(b, p)| (Some(b), Some(p)));
        let (bdpt, pt) = rayon::join(
            || renders.pair(&Integrator::Bdpt, upto, rb),
            || renders.pair(&Integrator::Pt, upto, rp),
        );
        Ok::<_, RenderError>((bdpt?, pt?))
    };
    let variances = |(bdpt, pt): &(Pair, Pair), n| variances(pt, bdpt, n);
    let first = both(looks.first, None)?;
    let (pt, bdpt) = variances(&first, looks.first);
    if looks.decides(
        pt / bdpt,
        BOUNCE_FINDS_THE_LIGHT / CLEAR_MARGIN,
        BOUNCE_FINDS_THE_LIGHT * CLEAR_MARGIN,
    ) {
        return Ok((first.0, looks.first, pt, bdpt));
    }
    let last = both(looks.last, Some(first))?;
    let (pt, bdpt) = variances(&last, looks.last);
    Ok((last.0, looks.last, pt, bdpt))
}

/// Stage 2, gathering against `bdpt` (stage 1's pair, continued where it ran fewer passes
/// than the first look), at `looks`: their variances, both over the same passes, and those
/// passes.
fn stage_two(renders: &Renders, bdpt: Pair, looks: Looks) -> Result<(f64, f64, u32), RenderError> {
    let gathering = |p: Passes| renders.gathering(p);
    let first = looks.first;
    let (g, b) = rayon::join(
        || renders.pair(&gathering, first, None),
        || renders.pair(&Integrator::Bdpt, first, Some(bdpt)),
    );
    let (first_g, first_b) = (g?, b?);
    let (g, b) = variances(&first_g, &first_b, first);
    if looks.decides(
        b / (g * GATHERING_PASS_COST),
        STAGE_TWO_BDPT_BELOW,
        CLEAR_MARGIN,
    ) {
        return Ok((g, b, first));
    }
    let (b, g) = rayon::join(
        || renders.pair(&Integrator::Bdpt, looks.last, Some(first_b)),
        || renders.pair(&gathering, looks.last, Some(first_g)),
    );
    let (g, b) = variances(&g?, &b?, looks.last);
    Ok((g, b, looks.last))
}

#[cfg(test)]
mod tests;
