//! The engine's one entry point: [`run`] renders a scene as a [`RenderSpec`] says. The CLI,
//! `sweep` and the server call it (and nothing deeper), so a new integrator is a variant of
//! `spec::Integrator` and an arm of the `match` here (and of the cost model beside it,
//! `budget.rs`); tests/architecture.rs checks that no other module dispatches on the
//! integrator.

mod auto;
mod budget;
mod pilot;

pub use budget::{Needs, ProgressModel};

use std::ops::ControlFlow;
use std::sync::Arc;
use std::time::Instant;

use crate::render::bidir::{BidirPasses, Modes};
use crate::render::control::{Cancelled, Control};
use crate::render::effects::{Analysis, analyse};
use crate::render::film::Image;
use crate::render::oneshot::render_with_maps;
use crate::render::outcome::{RenderError, RenderOutput};
use crate::render::photon::{PhotonMaps, PhotonParams, build_photon_maps};
use crate::render::ppm::{PpmPasses, PpmState};
pub use crate::render::progressive::Piece;
use crate::render::progressive::{Progression, ProgressiveRun, run_passes};
use crate::render::scene::Scene;
use crate::render::stats::{AutoChoice, Effect};
use crate::spec::{Integrator, Passes, RenderSpec, SpecForm};

/// Where a one-shot render's photon maps come from: traced now ([`TraceNow`]), given
/// ([`Prebuilt`]), or a cache (the server's). Progressive passes always trace their own
/// (each pass's maps are new random numbers, used once).
pub trait MapSource: Sync {
    /// The maps `want` asks for, and whether this call traced them.
    fn photon_maps(&self, want: &MapRequest) -> Result<SuppliedMaps, Cancelled>;
}

/// The photon maps of a scene for some photon parameters.
pub struct MapRequest<'a> {
    pub scene: &'a Scene,
    pub params: &'a PhotonParams,
    pub control: &'a Control<'a>,
}

impl MapRequest<'_> {
    /// Trace them.
    pub fn trace(&self) -> Result<PhotonMaps, Cancelled> {
        build_photon_maps(self.scene, self.params, self.control)
    }
}

/// Photon maps as a [`MapSource`] gives them.
pub struct SuppliedMaps {
    pub maps: Arc<PhotonMaps>,
    /// False when the maps were traced before (the render reports no tracing time).
    pub traced: bool,
}

/// Trace the maps now.
pub struct TraceNow;

impl MapSource for TraceNow {
    fn photon_maps(&self, want: &MapRequest) -> Result<SuppliedMaps, Cancelled> {
        let maps = Arc::new(want.trace()?);
        Ok(SuppliedMaps { maps, traced: true })
    }
}

/// Maps traced before (by `render::trace_maps`), used when they are the ones a render
/// needs; other parameters are traced now.
pub struct Prebuilt(pub Arc<PhotonMaps>);

impl MapSource for Prebuilt {
    fn photon_maps(&self, want: &MapRequest) -> Result<SuppliedMaps, Cancelled> {
        if self.0.params != *want.params {
            return TraceNow.photon_maps(want);
        }
        let maps = self.0.clone();
        Ok(SuppliedMaps {
            maps,
            traced: false,
        })
    }
}

/// What a render takes besides the scene, the spec and the caller's hooks.
pub struct Inputs<'a> {
    pub maps: &'a dyn MapSource,
    /// An image to measure the render against (relmse, block_err, mean_ratio; a
    /// progressive render after every pass).
    pub reference: Option<&'a Image>,
    /// A progressive render's saved state to continue from (the same bytes as never
    /// stopping); refused if it is not of this scene and spec.
    pub resume: Option<PpmState>,
    /// Identifies the scene: its source text, or any text that changes when it does. A
    /// progressive render's state is fingerprinted by it and the spec.
    pub scene_key: &'a [u8],
    /// Render only these passes of a progressive render (a farm's task; see [`Piece`]):
    /// the output's image is then of no use, the caller takes the piece's exact sum from
    /// the state `on_pass` sees after its last pass.
    pub piece: Option<Piece>,
    /// Render only these rows of a one-shot render's image (a farm's tile; see [`Rows`]).
    pub rows: Option<Rows>,
    /// What `auto` chose for this render before (a farm worker's earlier piece of the job):
    /// taken instead of a pilot, as a resumed state's own choice is, but its seconds are
    /// not counted again in `times.choose` (a farm sums its pieces' times).
    pub choice: Option<AutoChoice>,
}

/// Rows `first .. first + count` of a one-shot render's image: the output image is that
/// band, each of its pixels the bits it has in the whole image (a pixel's samples draw from
/// its own random streams, `render_film`), so bands rendered apart, even on other
/// machines over maps traced again from the same seed, make up the image of one run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rows {
    pub first: u32,
    pub count: u32,
}

impl Inputs<'_> {
    /// Maps traced now, no reference, nothing to resume.
    pub fn fresh() -> Inputs<'static> {
        Inputs {
            maps: &TraceNow,
            reference: None,
            resume: None,
            scene_key: b"",
            piece: None,
            rows: None,
            choice: None,
        }
    }
}

/// Called with the running state after every progressive pass; `Break` stops the render
/// after that pass (to give way, or to save and exit). One-shot renders never call it.
pub type OnPass<'a> = &'a mut dyn FnMut(&PpmState) -> ControlFlow<()>;

/// Render `scene` as `spec` says.
pub fn run(
    scene: &Scene,
    spec: &RenderSpec,
    inputs: Inputs,
    control: &Control,
    on_pass: OnPass,
) -> Result<RenderOutput, RenderError> {
    spec.validate()?;
    check_reference(scene, spec, inputs.reference)?;
    // The job's identity is its spec as given; what renders may be auto's choice.
    let fingerprint = fingerprint(inputs.scene_key, spec);
    let chosen = match &spec.integrator {
        Integrator::Auto(passes) => Some(choose(scene, spec, passes, &inputs, control)?),
        _ => None,
    };
    let spec = chosen.as_ref().map_or(spec, |c| &c.spec);
    let analysis = analyse(scene, spec);
    let mut out = match &spec.integrator {
        Integrator::Raytrace(_) | Integrator::Photon(_) => {
            one_shot(scene, spec, &analysis, inputs, control)?
        }
        _ => progressive(
            scene,
            spec,
            &analysis,
            inputs,
            (fingerprint, chosen.as_ref()),
            control,
            on_pass,
        )?,
    };
    if let Some(c) = chosen {
        let times = &mut out.stats.times;
        times.choose = c.seconds;
        times.total += c.seconds;
        out.stats.effects.insert("integrator".into(), c.effect);
    }
    Ok(out)
}

/// `auto` resolved: the spec that renders, why, and the seconds the choice took (when it was
/// made, for a kept one).
struct Chosen {
    spec: RenderSpec,
    effect: Effect,
    seconds: f64,
}

/// `auto`'s choice for `spec` (whose integrator is `Auto(passes)`): the one the caller or a
/// resumed state kept, if it still parses, else the choice made now.
fn choose(
    scene: &Scene,
    spec: &RenderSpec,
    passes: &Passes,
    inputs: &Inputs,
    control: &Control,
) -> Result<Chosen, RenderError> {
    let has_reference = inputs.reference.is_some();
    // The caller's choice was made by other work than this render's: it reports no seconds.
    let given = (inputs.choice.as_ref())
        .and_then(|c| auto::recorded(c, spec, has_reference))
        .map(|c| Chosen { seconds: 0.0, ..c });
    let kept = || {
        let state = inputs.resume.as_ref()?;
        auto::recorded(state.choice.as_ref()?, spec, has_reference)
    };
    if let Some(c) = given.or_else(kept) {
        return Ok(c);
    }
    let t0 = Instant::now();
    let (width, height) = spec.resolution((scene.camera.width, scene.camera.height));
    let pixels = width as u64 * height as u64;
    let (integrator, effect) = auto::choose(scene, spec, passes, pixels, control)?;
    Ok(Chosen {
        spec: RenderSpec {
            integrator,
            ..spec.clone()
        },
        effect,
        seconds: t0.elapsed().as_secs_f64(),
    })
}

/// The passes of a progressive integrator, from `inputs`' state if it has one;
/// `fingerprint` names the job as given, `chosen` what `auto` made of it.
fn progressive(
    scene: &Scene,
    spec: &RenderSpec,
    analysis: &Analysis,
    inputs: Inputs,
    (fingerprint, chosen): (String, Option<&Chosen>),
    control: &Control,
    on_pass: OnPass,
) -> Result<RenderOutput, RenderError> {
    let (width, height) = spec.resolution((scene.camera.width, scene.camera.height));
    let camera = scene.camera.clone().with_resolution(width, height);
    let bidir = |modes| BidirPasses::new(scene, spec, analysis, camera.clone(), modes);
    let mut progression: Box<dyn Progression> = match &spec.integrator {
        Integrator::Ppm(ppm) => Box::new(PpmPasses::new(scene, spec, ppm, analysis, camera)),
        Integrator::Pt(_) => Box::new(bidir(Modes::Pt)),
        Integrator::Lt(_) => Box::new(bidir(Modes::Lt)),
        Integrator::Bdpt(_) => Box::new(bidir(Modes::Bdpt)),
        Integrator::Vcm(_) => Box::new(bidir(Modes::Vcm)),
        Integrator::Raytrace(_) | Integrator::Photon(_) => unreachable!("one-shot"),
        Integrator::Auto(_) => unreachable!("auto is resolved before"),
    };
    if inputs.rows.is_some() {
        return Err(RenderError::Input(
            "a band of rows is only of a one-shot render (raytrace, photon)".into(),
        ));
    }
    let stop = spec.stop().expect("the progressive integrators stop");
    let run = ProgressiveRun {
        reference: inputs.reference,
        resume: inputs.resume,
        fingerprint,
        stop,
        seed: spec.seed,
        radius: spec.merge_radius().map(|(alpha, r)| (alpha, r.is_some())),
        size: (width, height),
        piece: inputs.piece,
        choice: chosen.map(|c| AutoChoice {
            params: serde_json::to_value(SpecForm::of(&c.spec)).unwrap_or_default(),
            effect: c.effect.clone(),
            seconds: c.seconds,
        }),
    };
    run_passes(progression.as_mut(), run, control, on_pass)
}

/// [`run`] with maps traced now, no reference, no state and no per-pass hook.
pub fn render(
    scene: &Scene,
    spec: &RenderSpec,
    control: &Control,
) -> Result<RenderOutput, RenderError> {
    run(scene, spec, Inputs::fresh(), control, &mut |_| {
        ControlFlow::Continue(())
    })
}

/// Photon maps (when the integrator reads any) and one camera pass over them.
fn one_shot(
    scene: &Scene,
    spec: &RenderSpec,
    analysis: &Analysis,
    inputs: Inputs,
    control: &Control,
) -> Result<RenderOutput, RenderError> {
    if inputs.resume.is_some() || inputs.piece.is_some() {
        return Err(RenderError::Input(format!(
            "a saved state or a piece of passes is only of a progressive render ({})",
            crate::spec::progressive_names()
        )));
    }
    let (_, height) = spec.resolution((scene.camera.width, scene.camera.height));
    let rows = match inputs.rows {
        None => 0..height,
        Some(r) if r.count == 0 || r.first as u64 + r.count as u64 > height as u64 => {
            return Err(RenderError::Input(format!(
                "rows {}..{} are not rows of the {height}-row image",
                r.first,
                r.first as u64 + r.count as u64
            )));
        }
        Some(_) if inputs.reference.is_some() => {
            return Err(RenderError::Input(
                "a band of rows is not measured against a reference: render the whole image".into(),
            ));
        }
        Some(r) => r.first..r.first + r.count,
    };
    let pp = &analysis.photon_params;
    let supplied = if pp.global_photons + pp.caustic_photons == 0 {
        SuppliedMaps {
            maps: Arc::new(PhotonMaps::none(pp.clone())),
            traced: true,
        }
    } else {
        let want = MapRequest {
            scene,
            params: pp,
            control,
        };
        inputs.maps.photon_maps(&want)?
    };
    let mut out = render_with_maps(scene, &supplied.maps, spec, analysis, rows, control)?;
    if !supplied.traced {
        out.stats.maps_were_reused();
    }
    out.measure(inputs.reference)
        .map_err(|e| RenderError::Input(format!("the reference: {e}")))?;
    Ok(out)
}

/// A reference must have the output's size: refused before anything is rendered.
fn check_reference(
    scene: &Scene,
    spec: &RenderSpec,
    reference: Option<&Image>,
) -> Result<(), RenderError> {
    let (w, h) = spec.resolution((scene.camera.width, scene.camera.height));
    if let Some(r) = reference
        && (r.width, r.height) != (w, h)
    {
        return Err(RenderError::Input(format!(
            "the reference is {}x{}, the image {w}x{h}: render at the reference's size",
            r.width, r.height
        )));
    }
    let needs_reference = spec.stop().is_some_and(|s| s.target_error.is_some());
    if needs_reference && reference.is_none() {
        return Err(RenderError::Input(
            "target_error needs a reference to measure the error against".into(),
        ));
    }
    Ok(())
}

/// A stable identity of a scene (`scene_key`) and of what in the spec shapes the image
/// (all but when to stop): a progressive state resumes only a render with the same one.
pub fn fingerprint(scene_key: &[u8], spec: &RenderSpec) -> String {
    let mut form = SpecForm::of(spec);
    (form.iterations, form.time_limit, form.target_error) = (None, None, None);
    let text = serde_json::to_string(&form).unwrap_or_default();
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    for b in scene_key.iter().chain(text.as_bytes()) {
        h = (h ^ *b as u64).wrapping_mul(0x0100_0000_01b3);
    }
    format!("{h:016x}")
}
