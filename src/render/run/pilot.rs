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
//! of its own, [`PILOT_PASSES`] passes each, and compares per-pass variances (the squared
//! difference between a pair, relative as `relmse` weighs it), in two stages:
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
//! Each stage looks first after [`FIRST_LOOK`] passes and decides there where its ratio
//! lies clearly on one side of its threshold ([`CLEAR_MARGIN`]); otherwise its renders
//! continue from their states to [`PILOT_PASSES`] (the same bytes as one render of that
//! many), and it decides as it did before the first look was added. Most rooms are clear
//! after 4 (a washed wall, a point light's hot spot, an open box under a ceiling light):
//! the pilot took about half the time there, with the same choices.
//!
//! Before 2026-12-05 the first stage decided alone, and chose `bdpt` on cornell_spheres,
//! where gathering is 1.3-3x sooner. A function of the scene and the spec alone (the
//! pilot's bytes do not depend on the thread count or the clock), so the choice is the
//! same on every run.

use std::ops::ControlFlow;

use super::Inputs;
use super::auto::GatherShape;
use crate::render::control::Control;
use crate::render::film::Image;
use crate::render::outcome::RenderError;
use crate::render::ppm::PpmState;
use crate::render::sampling::splitmix64;
use crate::render::scene::Scene;
use crate::spec::{Integrator, Passes, RenderSpec, Stop};

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

/// Passes of each pilot render. With the pixels weighed by `bdpt`'s mean
/// ([`pass_variance`]) 8 tell the rooms apart as 16 did, seeds 1-5: the first stage's pt/bdpt
/// 1.7-2.4 on cornell and knot against 6.2-6.6 on cornell_spheres and 23-37 where a light
/// washes a wall; the second stage's bdpt/gathering over the pass cost 1.9-2.1 on
/// cornell_spheres, 0.5-0.6 and under 0.03 on a washed wall lit by a rectangle and by a
/// parallelogram (docs/performance-history.md, "the pilot weighed by bdpt's mean").
const PILOT_PASSES: u32 = 8;

/// Passes after which the pilot first looks: where a stage's ratio lies beyond
/// [`CLEAR_MARGIN`] of its threshold either way it decides there, else its renders continue
/// (from their states: the same bytes) to [`PILOT_PASSES`] and it decides as before.
const FIRST_LOOK: u32 = 4;

/// How far a ratio must lie from its threshold (times or over) for the first look to
/// decide. Seeds 1-5 at 256x256 (docs/performance-history.md, "the pilot's first look"):
/// stage 1's ratio after 4 passes lay within 1.25 times of its value after 8 where it was
/// near the threshold (cornell, knot, a room lit by two sphere lights), 1.6 times where it
/// was far (a washed wall, 21-48 against 23-37); stage 2's read 0.72-0.81 of it. Every
/// first look beyond 1.4 chose as the eighth pass did.
const CLEAR_MARGIN: f64 = 1.4;

/// How the second stage's gathering spends its rays, and so the render's where it ran:
/// where `pt`'s bounce finds the light poorly, more rays a camera sample.
const SECOND_STAGE_SHAPE: GatherShape = GatherShape::OnOneSample;

/// The fewest photons a pilot pass of gathering traces, however small the image.
const MIN_PILOT_PHOTONS: u64 = 1_000;

/// A pilot render's image, and its state to continue from.
struct Look {
    image: Image,
    state: PpmState,
}

/// A pair of pilot renders of one integrator under the pilot's two seeds.
type Pair = [Look; 2];

/// Whether `ratio` is clearly below `threshold` (Some(false)) or above it (Some(true)):
/// beyond [`CLEAR_MARGIN`] either way; None where it is close.
fn verdict(ratio: f64, threshold: f64) -> Option<bool> {
    if ratio < threshold / CLEAR_MARGIN {
        Some(false)
    } else if ratio > threshold * CLEAR_MARGIN {
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
    /// The passes of the deciding stage's renders ([`FIRST_LOOK`] or [`PILOT_PASSES`]).
    pub passes: u32,
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

/// The pilot of `spec` (its seed, depth and effect switches) on `scene`, cancelled with
/// `control`: `pt` against `bdpt`, then, where `pt` did poorly, gathering against `bdpt`.
pub(super) fn run_pilot(
    scene: &Scene,
    spec: &RenderSpec,
    control: &Control,
) -> Result<Pilot, RenderError> {
    pilot_looking_first_at(scene, spec, control, FIRST_LOOK)
}

/// [`run_pilot`] with its first look after `first_look` passes ([`PILOT_PASSES`]: none).
fn pilot_looking_first_at(
    scene: &Scene,
    spec: &RenderSpec,
    control: &Control,
    first_look: u32,
) -> Result<Pilot, RenderError> {
    let renders = Renders::new(scene, spec, control);
    let (bdpt_pair, passes, pt, bdpt) = stage_one(&renders, first_look)?;
    if pt <= BOUNCE_FINDS_THE_LIGHT * bdpt {
        return Ok(Pilot {
            pt,
            bdpt,
            gathering: None,
            passes,
        });
    }
    let (gathering, bdpt, passes) = stage_two(&renders, bdpt_pair, passes)?;
    Ok(Pilot {
        pt,
        bdpt,
        gathering: Some(gathering),
        passes,
    })
}

/// Stage 1, `pt` against `bdpt`: `bdpt`'s pair, the passes it ran, and the two variances.
fn stage_one(renders: &Renders, first_look: u32) -> Result<(Pair, u32, f64, f64), RenderError> {
    let both = |upto: u32, resume: Option<(Pair, Pair)>| {
        let (rb, rp) = resume.map_or((None, None), |(b, p)| (Some(b), Some(p)));
        let (bdpt, pt) = rayon::join(
            || renders.pair(&Integrator::Bdpt, upto, rb),
            || renders.pair(&Integrator::Pt, upto, rp),
        );
        Ok::<_, RenderError>((bdpt?, pt?))
    };
    let variances =
        |(bdpt, pt): &(Pair, Pair), n| (pass_variance(pt, bdpt, n), pass_variance(bdpt, bdpt, n));
    let first = both(first_look, None)?;
    let (pt, bdpt) = variances(&first, first_look);
    if first_look >= PILOT_PASSES || verdict(pt / bdpt, BOUNCE_FINDS_THE_LIGHT).is_some() {
        return Ok((first.0, first_look, pt, bdpt));
    }
    let looks = both(PILOT_PASSES, Some(first))?;
    let (pt, bdpt) = variances(&looks, PILOT_PASSES);
    Ok((looks.0, PILOT_PASSES, pt, bdpt))
}

/// Stage 2, gathering against `bdpt` (whose pair ran `passes`): their variances, both over
/// the same passes, and those passes.
fn stage_two(renders: &Renders, bdpt: Pair, passes: u32) -> Result<(f64, f64, u32), RenderError> {
    let gathering = |p: Passes| renders.gathering(p);
    let variances = |g: &Pair, b: &Pair, n| (pass_variance(g, b, n), pass_variance(b, b, n));
    let first = renders.pair(&gathering, passes, None)?;
    let (g, b) = variances(&first, &bdpt, passes);
    if passes >= PILOT_PASSES || verdict(b / (g * GATHERING_PASS_COST), 1.0).is_some() {
        return Ok((g, b, passes));
    }
    let (b, g) = rayon::join(
        || renders.pair(&Integrator::Bdpt, PILOT_PASSES, Some(bdpt)),
        || renders.pair(&gathering, PILOT_PASSES, Some(first)),
    );
    let (g, b) = variances(&g?, &b?, PILOT_PASSES);
    Ok((g, b, PILOT_PASSES))
}

/// The pilot's small renders of one job: its image size, seeds and cancellation.
struct Renders<'a> {
    scene: &'a Scene,
    spec: &'a RenderSpec,
    quiet: Control<'a>,
    /// The pilot image's size, and the render's.
    size: (u32, u32),
    render_size: (u32, u32),
}

impl<'a> Renders<'a> {
    fn new(scene: &'a Scene, spec: &'a RenderSpec, control: &Control<'a>) -> Renders<'a> {
        let (w, h) = spec.resolution((scene.camera.width, scene.camera.height));
        let aspect = (w as f64 / h as f64).sqrt();
        let width = ((PILOT_PIXELS.sqrt() * aspect).round() as u32).clamp(4, 256);
        let height = ((PILOT_PIXELS.sqrt() / aspect).round() as u32).clamp(4, 256);
        Renders {
            scene,
            spec,
            quiet: Control {
                cancel: control.cancel,
                progress: None,
            },
            size: (width, height),
            render_size: (w, h),
        }
    }

    /// A render of `integrator` (made for a pass count) under the pilot's seed `k`, to pass
    /// `upto`, continued from `resume` if given: the same bytes as one render of `upto`
    /// passes.
    fn look(
        &self,
        integrator: &Made<'_>,
        k: u64,
        upto: u32,
        resume: Option<PpmState>,
    ) -> Result<Look, RenderError> {
        let spec = self.spec;
        let pilot = RenderSpec {
            width: Some(self.size.0),
            height: Some(self.size.1),
            seed: splitmix64(splitmix64(spec.seed ^ 0x7069_6c6f_7400_0000).wrapping_add(k)),
            integrator: integrator(Passes {
                spp: 1,
                stop: Stop::after(upto),
            }),
            ..spec.clone()
        };
        let mut state = None;
        let mut keep = |s: &PpmState| {
            state = Some(s.clone());
            ControlFlow::Continue(())
        };
        let inputs = Inputs {
            resume,
            ..Inputs::fresh()
        };
        let image = super::run(self.scene, &pilot, inputs, &self.quiet, &mut keep)?.image;
        let state = state.ok_or_else(|| RenderError::Input("a pilot render ran no pass".into()))?;
        Ok(Look { image, state })
    }

    /// A pair's two renders, side by side: a pilot image's passes are too small to keep
    /// every thread busy alone (each render's bytes are the same either way).
    fn pair(
        &self,
        integrator: &Made<'_>,
        upto: u32,
        resume: Option<Pair>,
    ) -> Result<Pair, RenderError> {
        let [ra, rb] = resume.map_or([None, None], |[a, b]| [Some(a.state), Some(b.state)]);
        let (a, b) = rayon::join(
            || self.look(integrator, 1, upto, ra),
            || self.look(integrator, 2, upto, rb),
        );
        Ok([a?, b?])
    }

    /// `auto`'s gathering as the pilot renders it, for `passes`.
    fn gathering(&self, passes: Passes) -> Integrator {
        let mut g = super::auto::gathering(&passes, SECOND_STAGE_SHAPE);
        // As many photons a pilot pixel as the render will have a pixel.
        let (width, height) = self.size;
        let (w, h) = self.render_size;
        let scale = (width * height) as f64 / (w as f64 * h as f64);
        let scaled = |n: u64| {
            ((n as f64 * scale).round() as u64)
                .max(MIN_PILOT_PHOTONS)
                .min(n)
        };
        g.pass.photons = scaled(g.pass.photons);
        g.pass.caustic_photons = scaled(g.pass.caustic_photons);
        // Unsmoothed, as the thresholds were measured: smoothing lowers a pass's variance
        // by a blur, which a variance does not charge, so it would tip the choice toward
        // gathering where its gather rays find the light poorly (a washed wall).
        g.gather_smoothing = 0.0;
        // One shadow ray a light, as the thresholds were measured (more lowers gathering's
        // variance under an area light: the choice stays the one made before they were
        // added).
        g.pass.shadow_rays = 1;
        Integrator::Ppm(g)
    }
}

/// An integrator made for a pass count.
type Made<'m> = dyn Fn(Passes) -> Integrator + Sync + 'm;

/// An integrator's per-pass variance from a pair of its pilot images (each the mean of
/// `passes` passes): a pair's squared difference is twice the variance of a mean,
/// weighed by 1 / (m^2 + 0.01) with m the mean of `bdpt`'s pair `weigh_by` (as `relmse`
/// weighs an error by the reference), the same weight for every integrator compared.
/// `bdpt`'s images are the steadier ones wherever the choice is close; a mean that also
/// held the measured integrator's images would rise with its own fireflies and discount
/// them: with it, a washed wall's pt/bdpt read 4.4-5.9 after 16 passes and 1.9-2.5 after 8,
/// below [`BOUNCE_FINDS_THE_LIGHT`].
fn pass_variance([a, b]: &Pair, weigh_by: &Pair, passes: u32) -> f64 {
    let [a, b, x, y] = [a, b, &weigh_by[0], &weigh_by[1]].map(|l| &l.image);
    let mut sum = 0.0;
    for i in 0..a.pixels.len() {
        for c in 0..3 {
            let [a, b, x, y] = [a, b, x, y].map(|im| im.pixels[i][c] as f64);
            let weight = 1.0 / (((x + y) / 2.0).powi(2) + 0.01);
            sum += (a - b).powi(2) * weight;
        }
    }
    sum * passes as f64 / 2.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::spec::Progressive;

    /// A white box 2 wide lit by `light` (JSON).
    fn box_lit_by(light: &str) -> Scene {
        let wall = |c: &str, u: &str, v: &str| {
            format!(
                r#"{{"type": "quad", "material": "white", "corner": {c}, "edge_u": {u}, "edge_v": {v}}}"#
            )
        };
        let walls = [
            wall("[-1, 0, -1]", "[0, 0, 2]", "[2, 0, 0]"),
            wall("[-1, 2, -1]", "[2, 0, 0]", "[0, 0, 2]"),
            wall("[-1, 0, -1]", "[2, 0, 0]", "[0, 2, 0]"),
            wall("[-1, 0, -1]", "[0, 2, 0]", "[0, 0, 2]"),
            wall("[1, 0, -1]", "[0, 0, 2]", "[0, 2, 0]"),
        ]
        .join(", ");
        let json = format!(
            r#"{{"camera": {{"position": [0, 1, 3.9], "look_at": [0, 1, 0], "up": [0, 1, 0],
                 "fov": 37, "width": 64, "height": 64}},
               "materials": {{"white": {{"type": "diffuse", "albedo": [0.75, 0.75, 0.75]}}}},
               "objects": [{walls}], "lights": [{light}]}}"#
        );
        Scene::parse(&json, None).expect("the test scene parses")
    }

    /// The first look decides as eight passes do, and decides early where the rooms are
    /// clear: an open box under a ceiling light (gathering by stage 1), a light washing the
    /// wall it faces from 2 cm (`bdpt` by stage 2); a point light's hot spot (gathering by
    /// stage 2, whose first look reads 0.7-0.8 of its eighth pass's ratio) takes either way.
    #[test]
    fn the_first_look_chooses_as_eight_passes_do() {
        let spec = RenderSpec::ppm(Progressive::DEFAULT);
        let rooms = [
            (
                r#"{"type": "quad", "corner": [-0.3, 1.998, -0.3], "edge_u": [0.6, 0, 0],
                    "edge_v": [0, 0, 0.6], "radiance": [12, 12, 12]}"#,
                false,
                true,
            ),
            (
                r#"{"type": "quad", "corner": [-0.5, 0.6, -0.98], "edge_u": [0, 0.8, 0],
                    "edge_v": [1, 0, 0], "radiance": [20, 20, 20]}"#,
                true,
                true,
            ),
            (
                r#"{"type": "point", "position": [0, 1.75, 0], "power": [30, 30, 30]}"#,
                false,
                false,
            ),
        ];
        for (light, bdpt, early) in rooms {
            let scene = box_lit_by(light);
            let control = Control::none();
            let first = run_pilot(&scene, &spec, &control).unwrap();
            let eight = pilot_looking_first_at(&scene, &spec, &control, PILOT_PASSES).unwrap();
            assert_eq!(eight.passes, PILOT_PASSES);
            assert_eq!(first.prefers_bdpt(), bdpt, "{light}: {first:?}");
            assert_eq!(eight.prefers_bdpt(), bdpt, "{light}: {eight:?}");
            assert_eq!(first.gather_shape(), eight.gather_shape(), "{light}");
            if early {
                assert_eq!(first.passes, FIRST_LOOK, "{light}: {first:?}");
            }
        }
    }
}
