//! Terminal progress bars, one per render phase (indicatif).

use std::collections::HashMap;
use std::sync::Mutex;

use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use photonbox::render::{Phase, Progress};

pub struct Bars {
    multi: MultiProgress,
    bars: Mutex<HashMap<&'static str, ProgressBar>>,
}

impl Bars {
    pub fn new() -> Bars {
        Bars {
            multi: MultiProgress::new(),
            bars: Mutex::new(HashMap::new()),
        }
    }

    pub fn update(&self, p: Progress) {
        let mut bars = self.bars.lock().unwrap_or_else(|e| e.into_inner());
        let bar = bars.entry(p.phase.name()).or_insert_with(|| {
            let bar = self.multi.add(ProgressBar::new(p.total));
            let style = ProgressStyle::with_template(
                "{msg:>12} [{bar:40}] {percent:>3}% {elapsed_precise} eta {eta}",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> ");
            bar.set_style(style);
            bar.set_message(label(p.phase));
            bar
        });
        bar.set_length(p.total);
        bar.set_position(p.done);
        if p.done >= p.total {
            bar.finish();
        }
    }

    pub fn clear(&self) {
        let _ = self.multi.clear();
    }
}

fn label(phase: Phase) -> &'static str {
    match phase {
        Phase::BuildScene => "scene",
        Phase::PhotonTrace => "photons",
        Phase::BuildMaps => "kd-trees",
        Phase::Precompute => "irradiance",
        Phase::Render => "render",
        Phase::Passes => "passes",
    }
}
