//! What the worker that completes a job's last task makes of the results: the job's image,
//! merged in task order ([`merge`]: pieces' exact sums to the bits of one run, or bands of
//! rows), its errors against a reference job's image, and the job's STATS.json composed
//! from its tasks' ([`job_stats`]).

use serde_json::{Value, json};

use super::Unit;
use crate::render::Image;
use crate::render::accuracy::{ImageError, compare};
use crate::render::ppm::PassSum;

/// How a piece's result begins: its sum follows, packed ([`PassSum::write_packed`], about a
/// quarter of the fixed layout's bytes on a real render: less for the store to write, keep
/// and send). A result without it is in the fixed layout ([`PassSum::write_to`]) that
/// workers before it wrote.
const PACKED: &[u8] = b"photonbox packed sum 1\n";

/// A piece's sum as a task's result.
pub(super) fn pack_sum(sum: &PassSum) -> Vec<u8> {
    let mut bytes = PACKED.to_vec();
    sum.write_packed(&mut bytes);
    bytes
}

/// The sum of a piece's result, if it is a `width` x `height` one.
pub(super) fn unpack_sum(width: u32, height: u32, bytes: &[u8]) -> Option<PassSum> {
    match bytes.strip_prefix(PACKED) {
        Some(packed) => PassSum::read_packed(width, height, packed),
        None => PassSum::read_from(width, height, bytes),
    }
}

/// The job's image merged from its units' results, and its errors against a reference.
pub struct Merged {
    pub image: Image,
    /// The image so far against the reference after each piece of passes (its last pass
    /// and the error), or the whole image's; empty without a reference.
    pub errors: Vec<(u32, ImageError)>,
}

/// The job's image from its units' results (in the job's task order), measured against
/// `reference` if there is one, or why not.
pub fn merge(
    size: (u32, u32),
    units: &[(Unit, Vec<u8>)],
    reference: Option<&Image>,
) -> Result<Merged, String> {
    let (width, height) = size;
    let measure = |image: &Image| {
        reference
            .map(|r| compare(image, r).map_err(|e| format!("the reference: {e}")))
            .transpose()
    };
    let image = match units {
        [(Unit::Whole, bytes)] => image_of(width, height, bytes)?,
        [(Unit::Rows { .. }, _), ..] => merge_rows(size, units)?,
        _ => return merge_passes(size, units, measure),
    };
    let errors = measure(&image)?.map(|e| (0, e)).into_iter().collect();
    Ok(Merged { image, errors })
}

/// The mean of pieces' exact sums, measured after each piece.
fn merge_passes(
    (width, height): (u32, u32),
    units: &[(Unit, Vec<u8>)],
    measure: impl Fn(&Image) -> Result<Option<ImageError>, String>,
) -> Result<Merged, String> {
    let mut errors = Vec::new();
    let mut sum = PassSum::new(width, height);
    let mut passes = 0u32;
    for (unit, bytes) in units {
        let Unit::Passes { count, .. } = unit else {
            return Err("a job mixes units of passes and others".into());
        };
        let piece = unpack_sum(width, height, bytes).ok_or_else(|| {
            format!(
                "a result of {} bytes is not a {width}x{height} sum",
                bytes.len()
            )
        })?;
        sum.merge(&piece);
        passes += count;
        if let Some(e) = measure(&sum.mean(passes))? {
            errors.push((passes, e));
        }
    }
    Ok(Merged {
        image: sum.mean(passes),
        errors,
    })
}

/// The image of bands that cover its rows once, in order.
fn merge_rows(size: (u32, u32), units: &[(Unit, Vec<u8>)]) -> Result<Image, String> {
    let (width, height) = size;
    let mut image = Image::new(width, height);
    let mut next = 0u32;
    for (unit, bytes) in units {
        let &Unit::Rows { first, count } = unit else {
            return Err("a job mixes bands of rows and other units".into());
        };
        if first != next || first as u64 + count as u64 > height as u64 {
            return Err(format!("rows {first}+{count} do not follow row {next}"));
        }
        let band = image_of(width, count, bytes)?;
        let at = first as usize * width as usize;
        image.pixels[at..at + band.pixels.len()].copy_from_slice(&band.pixels);
        next += count;
    }
    if next != height {
        return Err(format!("the bands end at row {next} of {height}"));
    }
    Ok(image)
}

pub(super) fn image_of(width: u32, height: u32, bytes: &[u8]) -> Result<Image, String> {
    let pixels = width as usize * height as usize;
    if bytes.len() != pixels * 12 {
        return Err(format!(
            "a result of {} bytes is not a {width}x{height} image",
            bytes.len()
        ));
    }
    let mut image = Image::new(width, height);
    for (px, chunk) in image.pixels.iter_mut().zip(bytes.chunks_exact(12)) {
        for (c, b) in px.iter_mut().zip(chunk.chunks_exact(4)) {
            *c = f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
        }
    }
    Ok(image)
}

/// The job's STATS.json from its tasks' (in task order; None where a task handed none in):
/// the last task's, with every task's times summed (the work, not the wall-clock), a
/// progressive job's pass history (the section holding `history`) joined (each piece's seconds counted on from the pieces'
/// before it), the errors against the reference (after each piece, on its last pass; the
/// last as the job's `error`), and the farm's own: how many tasks.
pub fn job_stats(tasks: &[Option<String>], errors: &[(u32, ImageError)]) -> Value {
    let parsed: Vec<Value> = tasks
        .iter()
        .map(|t| {
            t.as_deref()
                .and_then(|t| serde_json::from_str(t).ok())
                .unwrap_or(Value::Null)
        })
        .collect();
    let mut stats = parsed
        .iter()
        .rev()
        .find(|v| v.is_object())
        .cloned()
        .unwrap_or_else(|| json!({}));
    if let Some(times) = stats.get_mut("times").and_then(Value::as_object_mut) {
        for (phase, total) in times.iter_mut() {
            let sum: f64 = parsed
                .iter()
                .filter_map(|p| p["times"][phase].as_f64())
                .sum();
            *total = json!(sum);
        }
    }
    // The progressive report: the section that holds the pass history.
    let section = stats.as_object().and_then(|o| {
        o.iter()
            .find(|(_, v)| v["history"].is_array())
            .map(|(k, _)| k.clone())
    });
    if let Some(section) = section {
        let mut history = Vec::new();
        let mut before = 0.0;
        for piece in &parsed {
            let mut last = 0.0;
            for pass in piece[&section]["history"].as_array().into_iter().flatten() {
                let mut pass = pass.clone();
                last = pass["elapsed"].as_f64().unwrap_or(last);
                pass["elapsed"] = json!(before + last);
                history.push(pass);
            }
            before += last;
        }
        for (last_pass, error) in errors {
            let at = history.iter_mut().find(|p| p["pass"] == json!(last_pass));
            if let Some(pass) = at {
                pass["error"] = json!(error);
            }
        }
        stats[&section]["history"] = json!(history);
    }
    if let Some((_, error)) = errors.last() {
        stats["error"] = json!(error);
    }
    stats["farm"] = json!({ "tasks": tasks.len() });
    stats
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_whole_image_round_trips_and_a_short_result_is_refused() {
        let mut image = Image::new(3, 2);
        image.pixels[4] = [1.5, -0.0, f32::MIN_POSITIVE];
        let bytes: Vec<u8> = image
            .pixels
            .iter()
            .flatten()
            .flat_map(|c| c.to_le_bytes())
            .collect();
        let merged = merge((3, 2), &[(Unit::Whole, bytes.clone())], None).unwrap();
        assert!(merged.image == image && merged.errors.is_empty());
        let against = merge((3, 2), &[(Unit::Whole, bytes.clone())], Some(&image)).unwrap();
        assert_eq!(against.errors[0].1.relmse, 0.0);
        assert!(merge((3, 2), &[(Unit::Whole, bytes[1..].to_vec())], None).is_err());
    }

    /// Times add up, the pieces' passes follow on, each piece's last pass gets the error of
    /// the image so far, the job the last one's.
    #[test]
    fn a_job_s_stats_join_its_pieces() {
        let piece = |first: u32, elapsed: [f64; 2]| {
            json!({"times": {"render": 1.5, "total": 2.0}, "photons": {"global_stored": first},
                   "passes": {"last": first + 1, "history": [
                       {"pass": first, "elapsed": elapsed[0]},
                       {"pass": first + 1, "elapsed": elapsed[1]}]}})
            .to_string()
        };
        let error = |relmse| ImageError {
            relmse,
            ..ImageError::default()
        };
        let tasks = [Some(piece(1, [1.0, 2.0])), Some(piece(3, [0.5, 1.5]))];
        let s = job_stats(&tasks, &[(2, error(0.4)), (4, error(0.1))]);
        assert_eq!(s["times"], json!({"render": 3.0, "total": 4.0}));
        assert_eq!(s["photons"]["global_stored"], 3, "the last task's");
        let h = s["passes"]["history"].as_array().unwrap();
        let elapsed: Vec<f64> = h.iter().map(|p| p["elapsed"].as_f64().unwrap()).collect();
        assert_eq!(elapsed, [1.0, 2.0, 2.5, 3.5]);
        let relmse: Vec<Option<f64>> = h.iter().map(|p| p["error"]["relmse"].as_f64()).collect();
        assert_eq!(relmse, [None, Some(0.4), None, Some(0.1)]);
        assert_eq!(
            (s["error"]["relmse"].as_f64(), &s["farm"]),
            (Some(0.1), &json!({"tasks": 2}))
        );
        // A task that handed in no stats counts, and spoils nothing.
        let s = job_stats(&[None, Some(piece(3, [0.5, 1.5]))], &[]);
        assert_eq!(
            (s["farm"]["tasks"].as_u64(), s.get("error")),
            (Some(2), None)
        );
    }

    /// A piece's result reads back packed, and in the fixed layout of earlier workers.
    #[test]
    fn a_piece_s_sum_reads_back_packed_or_fixed() {
        let mut image = Image::new(2, 1);
        image.pixels = vec![[0.25, 3.0, 0.0], [1e-3, 7.5, 2.0]];
        let mut sum = PassSum::new(2, 1);
        sum.add_image(&image);
        let packed = pack_sum(&sum);
        assert_eq!(unpack_sum(2, 1, &packed), Some(sum.clone()));
        let mut fixed = Vec::new();
        sum.write_to(&mut fixed);
        assert_eq!(unpack_sum(2, 1, &fixed), Some(sum));
        assert_eq!(unpack_sum(2, 1, &packed[..packed.len() - 1]), None);
    }
}
