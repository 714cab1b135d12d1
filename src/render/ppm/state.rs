//! The running state of a progressive render: everything needed to continue it exactly, so
//! that a render stopped after pass j and resumed gives the same bytes as one that never
//! stopped (the passes' random numbers depend only on the seed and the pass index).
//!
//! File format 3: the line `photonbox-ppm-state 3`, a little-endian u64 header length, the
//! header as JSON, the exact sum image ([`PassSum`]: little-endian i128 RGB triples,
//! row-major), and last the SHA-256 of everything before it. A state with a flipped bit would otherwise resume
//! without complaint and give other bytes than the render it claims to continue; with the
//! digest, any change or truncation is [`StateError::Corrupt`] and the caller starts over.
//! Format 1 (the same without the digest) cannot be verified, and format 2 (an f64 sum)
//! cannot continue the exact sum, so both are refused as corrupt too: each costs one
//! restart from pass 0.

use std::io::{Read, Write};

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use super::sum::{PIXEL_BYTES, PassSum};
use crate::render::film::Image;
use crate::render::stats::{AutoChoice, PassStats, PassTotals};

const MAGIC: &[u8] = b"photonbox-ppm-state 3\n";

/// Format 1's first line: no digest.
const MAGIC_V1: &[u8] = b"photonbox-ppm-state 1\n";
/// Format 2's first line: an f64 sum.
const MAGIC_V2: &[u8] = b"photonbox-ppm-state 2\n";

/// Bytes of the trailing SHA-256.
const DIGEST: usize = 32;

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
    /// Absent from states written before it (they resume with a pilot).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    choice: Option<AutoChoice>,
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
    /// What `auto` chose, for a render of `auto`'s (continued without a second pilot).
    pub choice: Option<AutoChoice>,
    /// Sum of the passes' images, exact: the same bits however the passes were split.
    pub(crate) sum: PassSum,
}

#[derive(Debug, thiserror::Error)]
pub enum StateError {
    /// Nothing like a state (its first line is not, even nearly, a state's).
    #[error("not a photonbox PPM state file")]
    NotAState,
    /// A state whose bytes are not the ones written (checksum, truncation, format 1): the
    /// render cannot resume from it and must start from pass 0.
    #[error("corrupt state file: {reason}")]
    Corrupt { reason: String },
    #[error("{0}")]
    Io(#[from] std::io::Error),
}

fn corrupt(reason: impl Into<String>) -> StateError {
    StateError::Corrupt {
        reason: reason.into(),
    }
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
            choice: None,
            sum: PassSum::new(width, height),
        }
    }

    /// The image so far: the mean of the passes.
    pub fn image(&self) -> Image {
        self.sum.mean(self.passes)
    }

    /// The exact sum of the passes' images.
    pub fn sum(&self) -> &PassSum {
        &self.sum
    }

    /// Take the sum out, leaving zero: a render resumed from the state then sums only the
    /// passes it runs itself, a piece that merges exactly with the others
    /// ([`PassSum::merge`]; how a farm spreads one job's passes over machines).
    pub fn take_sum(&mut self) -> PassSum {
        std::mem::replace(&mut self.sum, PassSum::new(self.width, self.height))
    }

    /// Seconds spent in passes so far.
    pub fn elapsed(&self) -> f64 {
        self.last.as_ref().map_or(0.0, |h| h.elapsed)
    }

    /// Seconds `auto`'s choice took (its pilot), which a time limit counts with the passes.
    pub fn choosing(&self) -> f64 {
        self.choice.as_ref().map_or(0.0, |c| c.seconds)
    }

    /// Record a finished pass's statistics.
    pub(crate) fn record(&mut self, p: PassStats) {
        self.totals.photon_trace += p.photon_trace;
        self.totals.build_maps += p.build_maps;
        self.totals.render += p.render;
        if kept_in_history(p.pass) {
            self.history.push(p.clone());
        }
        self.last = Some(p);
    }

    pub(crate) fn add_pass(&mut self, pass: &Image) {
        self.sum.add_image(pass);
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
            choice: self.choice.clone(),
        };
        let json = serde_json::to_vec(&header).map_err(std::io::Error::other)?;
        let mut buf = Vec::with_capacity(MAGIC.len() + 8 + json.len());
        buf.extend_from_slice(MAGIC);
        buf.extend_from_slice(&(json.len() as u64).to_le_bytes());
        buf.extend_from_slice(&json);
        self.sum.write_to(&mut buf);
        let digest = Sha256::digest(&buf);
        w.write_all(&buf)?;
        w.write_all(&digest)?;
        w.flush()
    }

    /// Save to `path`, atomically (see [`crate::render::output::write_atomically`]).
    pub fn save_file(&self, path: &std::path::Path) -> std::io::Result<()> {
        crate::render::output::write_atomically(path, |tmp| {
            self.save(std::io::BufWriter::new(std::fs::File::create(tmp)?))
        })
    }

    /// Read a state, verifying its digest before anything else is trusted.
    pub fn load(mut r: impl Read) -> Result<PpmState, StateError> {
        let mut file = Vec::new();
        r.read_to_end(&mut file)?;
        // A flipped bit in the first line is corruption, not another kind of file.
        let alike = file.iter().zip(MAGIC).filter(|(a, b)| a == b).count();
        if alike * 2 < MAGIC.len() {
            return Err(StateError::NotAState);
        }
        if file.starts_with(MAGIC_V1) {
            return Err(corrupt("format 1, which has no checksum to verify it by"));
        }
        if file.starts_with(MAGIC_V2) {
            return Err(corrupt(
                "format 2, whose float sum the exact sum cannot continue",
            ));
        }
        if file.len() < MAGIC.len() + 8 + DIGEST {
            return Err(corrupt(format!("truncated ({} bytes)", file.len())));
        }
        let (body, digest) = file.split_at(file.len() - DIGEST);
        if Sha256::digest(body)[..] != *digest {
            return Err(corrupt("checksum mismatch (changed or truncated)"));
        }
        let Some(rest) = body.strip_prefix(MAGIC) else {
            return Err(corrupt("unknown format"));
        };
        let (len, rest) = rest.split_at(8);
        let len = u64::from_le_bytes(len.try_into().expect("8 bytes"));
        if len > rest.len() as u64 {
            return Err(corrupt(format!("header of {len} bytes")));
        }
        let (json, bytes) = rest.split_at(len as usize);
        let h: Header = serde_json::from_slice(json).map_err(|e| corrupt(e.to_string()))?;
        // The sum's size is checked against the header's before anything is allocated.
        let sum = PassSum::read_from(h.width, h.height, bytes).ok_or_else(|| {
            corrupt(format!(
                "{} bytes of image for {}x{} pixels ({PIXEL_BYTES} a pixel)",
                bytes.len(),
                h.width,
                h.height
            ))
        })?;
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
            choice: h.choice,
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
        s.sum.add_image(&Image {
            width: 3,
            height: 2,
            pixels: vec![[1.0 / 3.0, f32::MIN_POSITIVE, 1e30]; 6],
        });
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
            Err(StateError::Corrupt { .. })
        ));
    }
}

#[cfg(test)]
mod checksum_tests {
    use super::*;

    fn saved() -> (PpmState, Vec<u8>) {
        let mut s = PpmState::new("scene+params".into(), 4, 3);
        s.passes = 5;
        s.r2_global = 0.01;
        s.r2_caustic = 0.0004;
        s.sum.add_image(&Image {
            width: 4,
            height: 3,
            pixels: (0..12)
                .map(|i| [i as f32 * 0.25, 1.0 / (i + 1) as f32, 7.5])
                .collect(),
        });
        let mut buf = Vec::new();
        s.save(&mut buf).unwrap();
        (s, buf)
    }

    fn is_corrupt(bytes: &[u8]) -> bool {
        matches!(PpmState::load(bytes), Err(StateError::Corrupt { .. }))
    }

    /// Every single-bit flip, in the first line, the header length, the JSON header, the
    /// pixel sum or the digest itself, is caught as corruption.
    #[test]
    fn any_flipped_bit_is_corrupt() {
        let (s, buf) = saved();
        assert_eq!(PpmState::load(&buf[..]).unwrap(), s);
        for i in 0..buf.len() * 8 {
            let mut bad = buf.clone();
            bad[i / 8] ^= 1 << (i % 8);
            assert!(is_corrupt(&bad), "bit {i} of {} flipped", buf.len() * 8);
        }
    }

    #[test]
    fn truncated_and_format_1_states_are_corrupt() {
        let (_, buf) = saved();
        for len in [
            0,
            1,
            MAGIC.len(),
            MAGIC.len() + 8,
            buf.len() / 2,
            buf.len() - 1,
        ] {
            let r = PpmState::load(&buf[..len]);
            // Shorter than half the first line, a file is not recognisably a state.
            let want_corrupt = len * 2 >= MAGIC.len();
            assert_eq!(is_corrupt(&buf[..len]), want_corrupt, "{len} bytes: {r:?}");
        }
        // Format 1: the same bytes with the old first line and no digest.
        let mut v1 = MAGIC_V1.to_vec();
        v1.extend_from_slice(&buf[MAGIC.len()..buf.len() - DIGEST]);
        assert!(is_corrupt(&v1));
        let err = PpmState::load(&v1[..]).unwrap_err().to_string();
        assert!(err.contains("format 1"), "{err}");
        // Format 2: an f64 sum, with its digest.
        let mut v2 = MAGIC_V2.to_vec();
        v2.extend_from_slice(&buf[MAGIC.len()..buf.len() - DIGEST]);
        let digest = Sha256::digest(&v2);
        v2.extend_from_slice(&digest);
        let err = PpmState::load(&v2[..]).unwrap_err().to_string();
        assert!(err.contains("format 2"), "{err}");
    }
}
