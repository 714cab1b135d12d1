//! The running state of a progressive render: everything needed to continue it exactly, so
//! that a render stopped after pass j and resumed gives the same bytes as one that never
//! stopped (the passes' random numbers depend only on the seed and the pass index).
//!
//! File format: the line `photonbox-ppm-state 1`, a little-endian u64 header length, the
//! header as JSON, then the sum image as little-endian f64 RGB triples, row-major.

use std::io::{Read, Write};

use serde::{Deserialize, Serialize};

use crate::render::accuracy::ImageError;
use crate::render::film::Image;

const MAGIC: &[u8] = b"photonbox-ppm-state 1\n";

/// What one pass did.
#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
pub struct PassStats {
    /// 1-based.
    pub pass: u32,
    /// Radii of this pass's estimates (scene units; 0 where the map was not built).
    pub radius_global: f64,
    pub radius_caustic: f64,
    pub photon_trace: f64,
    pub build_maps: f64,
    pub render: f64,
    /// Seconds spent in all passes up to and including this one.
    pub elapsed: f64,
    pub global_stored: u64,
    pub caustic_stored: u64,
    /// The pass average so far against the reference, when there is one.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub error: Option<ImageError>,
}

/// Seconds summed over all passes, by phase.
#[derive(Serialize, Deserialize, Clone, Copy, Debug, Default, PartialEq)]
pub struct PassTotals {
    pub photon_trace: f64,
    pub build_maps: f64,
    pub render: f64,
}

/// Every pass up to this one is kept in the history; beyond it, passes are kept at
/// logarithmically spaced intervals (about this many per doubling), so that the state stays
/// small however many passes run.
const HISTORY_DENSE: u32 = 256;

/// Whether pass `pass` (1-based) is kept in the thinned history.
pub fn kept_in_history(pass: u32) -> bool {
    if pass <= HISTORY_DENSE {
        return true;
    }
    let step = 1u32 << (pass / HISTORY_DENSE).ilog2();
    pass.is_multiple_of(step)
}

#[derive(Serialize, Deserialize, Clone, Debug, PartialEq)]
struct Header {
    fingerprint: String,
    width: u32,
    height: u32,
    passes: u32,
    /// Squared radii as f64 bit patterns: JSON text need not round-trip an f64 exactly.
    r2_bits: [u64; 2],
    radius_initial: [f64; 2],
    nonfinite_samples: u64,
    totals: PassTotals,
    last: Option<PassStats>,
    history: Vec<PassStats>,
}

/// The state after some passes.
#[derive(Clone, Debug, PartialEq)]
pub struct PpmState {
    /// Identifies the scene and parameters (all but the stop conditions); a state resumes
    /// only a render with the same fingerprint.
    pub fingerprint: String,
    pub width: u32,
    pub height: u32,
    /// Passes done.
    pub passes: u32,
    /// Squared radii for the next pass (global, caustic), kept in f64 so the schedule is
    /// the same whether or not the render was interrupted.
    pub r2_global: f64,
    pub r2_caustic: f64,
    /// Initial radii (global, caustic); 0 until the first pass has set them.
    pub radius_initial: [f64; 2],
    pub nonfinite_samples: u64,
    /// Seconds of all passes, by phase.
    pub totals: PassTotals,
    /// The latest pass.
    pub last: Option<PassStats>,
    /// Passes kept for reports: all of the first 256, then thinned (see [`kept_in_history`]).
    pub history: Vec<PassStats>,
    /// Sum of the passes' images, in f64: the same sum in the same order on every run, and
    /// far from losing the f32 passes' precision at any pass count we allow.
    pub(super) sum: Vec<[f64; 3]>,
}

#[derive(Debug, thiserror::Error)]
pub enum StateError {
    #[error("not a photonbox PPM state file")]
    NotAState,
    #[error("corrupt state file: {0}")]
    Corrupt(String),
    #[error("{0}")]
    Io(#[from] std::io::Error),
}

impl PpmState {
    pub fn new(fingerprint: String, width: u32, height: u32) -> PpmState {
        PpmState {
            fingerprint,
            width,
            height,
            passes: 0,
            r2_global: 0.0,
            r2_caustic: 0.0,
            radius_initial: [0.0; 2],
            nonfinite_samples: 0,
            totals: PassTotals::default(),
            last: None,
            history: Vec::new(),
            sum: vec![[0.0; 3]; width as usize * height as usize],
        }
    }

    /// The image so far: the mean of the passes.
    pub fn image(&self) -> Image {
        let inv = 1.0 / self.passes.max(1) as f64;
        Image {
            width: self.width,
            height: self.height,
            pixels: self
                .sum
                .iter()
                .map(|p| p.map(|c| (c * inv) as f32))
                .collect(),
        }
    }

    /// Seconds spent in passes so far.
    pub fn elapsed(&self) -> f64 {
        self.last.as_ref().map_or(0.0, |h| h.elapsed)
    }

    /// Record a finished pass's statistics.
    pub(super) fn record(&mut self, p: PassStats) {
        self.totals.photon_trace += p.photon_trace;
        self.totals.build_maps += p.build_maps;
        self.totals.render += p.render;
        if kept_in_history(p.pass) {
            self.history.push(p.clone());
        }
        self.last = Some(p);
    }

    pub(super) fn add_pass(&mut self, pass: &Image) {
        for (s, p) in self.sum.iter_mut().zip(&pass.pixels) {
            for c in 0..3 {
                s[c] += p[c] as f64;
            }
        }
    }

    pub fn save(&self, mut w: impl Write) -> std::io::Result<()> {
        let header = Header {
            fingerprint: self.fingerprint.clone(),
            width: self.width,
            height: self.height,
            passes: self.passes,
            r2_bits: [self.r2_global.to_bits(), self.r2_caustic.to_bits()],
            radius_initial: self.radius_initial,
            nonfinite_samples: self.nonfinite_samples,
            totals: self.totals,
            last: self.last.clone(),
            history: self.history.clone(),
        };
        let json = serde_json::to_vec(&header).map_err(std::io::Error::other)?;
        w.write_all(MAGIC)?;
        w.write_all(&(json.len() as u64).to_le_bytes())?;
        w.write_all(&json)?;
        let mut buf = Vec::with_capacity(self.sum.len() * 24);
        for p in &self.sum {
            for c in p {
                buf.extend_from_slice(&c.to_le_bytes());
            }
        }
        w.write_all(&buf)?;
        w.flush()
    }

    /// Save to `path`, atomically (see [`crate::render::output::write_atomically`]).
    pub fn save_file(&self, path: &std::path::Path) -> std::io::Result<()> {
        crate::render::output::write_atomically(path, |tmp| {
            self.save(std::io::BufWriter::new(std::fs::File::create(tmp)?))
        })
    }

    pub fn load(mut r: impl Read) -> Result<PpmState, StateError> {
        let mut magic = vec![0u8; MAGIC.len()];
        r.read_exact(&mut magic)
            .map_err(|_| StateError::NotAState)?;
        if magic != MAGIC {
            return Err(StateError::NotAState);
        }
        let mut len = [0u8; 8];
        r.read_exact(&mut len)?;
        let len = u64::from_le_bytes(len);
        if len > 1 << 30 {
            return Err(StateError::Corrupt(format!("header of {len} bytes")));
        }
        let mut json = vec![0u8; len as usize];
        r.read_exact(&mut json)?;
        let h: Header =
            serde_json::from_slice(&json).map_err(|e| StateError::Corrupt(e.to_string()))?;
        let n = (h.width as usize)
            .checked_mul(h.height as usize)
            .filter(|n| *n <= 1 << 32)
            .ok_or_else(|| StateError::Corrupt(format!("{}x{} pixels", h.width, h.height)))?;
        let mut bytes = Vec::new();
        r.read_to_end(&mut bytes)?;
        if bytes.len() != n * 24 {
            return Err(StateError::Corrupt(format!(
                "{} bytes of image for {}x{} pixels",
                bytes.len(),
                h.width,
                h.height
            )));
        }
        let f = |i: usize| f64::from_le_bytes(bytes[i * 8..i * 8 + 8].try_into().unwrap());
        let sum = (0..n)
            .map(|i| [f(3 * i), f(3 * i + 1), f(3 * i + 2)])
            .collect();
        Ok(PpmState {
            fingerprint: h.fingerprint,
            width: h.width,
            height: h.height,
            passes: h.passes,
            r2_global: f64::from_bits(h.r2_bits[0]),
            r2_caustic: f64::from_bits(h.r2_bits[1]),
            radius_initial: h.radius_initial,
            nonfinite_samples: h.nonfinite_samples,
            totals: h.totals,
            last: h.last,
            history: h.history,
            sum,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn history_is_dense_then_thinned() {
        let kept = |a: u32, b: u32| (a..=b).filter(|&p| kept_in_history(p)).count();
        assert_eq!(kept(1, 256), 256);
        assert_eq!(kept(257, 511), 255);
        assert_eq!(kept(512, 1023), 256);
        assert_eq!(kept(1024, 2047), 256);
        assert!(kept(1, 1_000_000) < 256 * 14);
    }

    #[test]
    fn state_round_trips_exactly() {
        let mut s = PpmState::new("scene+params".into(), 3, 2);
        s.passes = 2;
        s.r2_global = 0.1f64.powi(2) * (1.7 / 2.0);
        s.sum[4] = [1.0 / 3.0, f64::MIN_POSITIVE, 1e300];
        s.record(PassStats {
            pass: 1,
            radius_global: 0.1,
            radius_caustic: 0.01,
            photon_trace: 0.5,
            build_maps: 0.1,
            render: 0.2,
            elapsed: 0.8,
            global_stored: 10,
            caustic_stored: 5,
            error: None,
        });
        // A value whose shortest decimal form a fast float parser may not round-trip.
        s.r2_caustic = 0.05f64.powi(2) * (2.0 + 2.0 / 3.0) / 3.0;
        let mut buf = Vec::new();
        s.save(&mut buf).unwrap();
        let back = PpmState::load(&buf[..]).unwrap();
        assert_eq!(back, s);
        assert_eq!(back.r2_caustic.to_bits(), s.r2_caustic.to_bits());
        assert!(matches!(
            PpmState::load(&b"not a state"[..]),
            Err(StateError::NotAState)
        ));
        assert!(matches!(
            PpmState::load(&buf[..buf.len() - 1]),
            Err(StateError::Corrupt(_))
        ));
    }
}
