//! Previews of a farm job while it runs, as `GET /api/jobs/{id}/image.png` (and `.exr`)
//! answers on one box: the mean of the passes that its done tasks rendered (a piece's exact
//! sum merged as the job's end would merge it), or the bands of rows done so far on black.
//! Any API instance makes them, from the results in the store. An instance keeps, for the
//! few jobs it previewed last, what it has merged and the encoded images, so a preview
//! asked again merges only the tasks done since, and costs one small query when none is;
//! one preview is made at a time per instance (the CPU and memory a client can ask for are
//! bounded whatever it polls).

use std::collections::BTreeSet;

use super::outcome::{image_of, unpack_sum};
use super::{Queue, Unit};
use crate::render::Image;
use crate::render::output;
use crate::render::ppm::PassSum;

/// The jobs whose merged results an instance keeps (least recently previewed dropped).
const KEPT_JOBS: usize = 4;

/// What the done tasks of a job add up to so far.
enum Partial {
    Passes { sum: PassSum, passes: u32 },
    Rows(Image),
}

impl Partial {
    fn add(&mut self, unit: Unit, bytes: &[u8]) -> Result<(), String> {
        match (self, unit) {
            (Partial::Passes { sum, passes }, Unit::Passes { count, .. }) => {
                let (w, h) = (sum.width, sum.height);
                let piece = unpack_sum(w, h, bytes)
                    .ok_or_else(|| format!("a result of {} bytes is not a sum", bytes.len()))?;
                sum.merge(&piece);
                *passes += count;
            }
            (Partial::Rows(image), Unit::Rows { first, count }) => {
                let band = image_of(image.width, count, bytes)?;
                let at = first as usize * image.width as usize;
                let end = at + band.pixels.len();
                if end > image.pixels.len() {
                    return Err(format!("rows {first}+{count} are outside the image"));
                }
                image.pixels[at..end].copy_from_slice(&band.pixels);
            }
            _ => return Err("a job mixes units of passes and others".into()),
        }
        Ok(())
    }

    fn image(&self) -> Image {
        match self {
            Partial::Passes { sum, passes } => sum.mean(*passes),
            Partial::Rows(image) => image.clone(),
        }
    }
}

/// One job's preview as an instance keeps it.
struct JobPreview {
    job_id: i64,
    merged: BTreeSet<i32>,
    partial: Option<Partial>,
    png: Vec<u8>,
    exr: Vec<u8>,
}

/// An API instance's previews.
#[derive(Default)]
pub struct Previews {
    kept: tokio::sync::Mutex<Vec<JobPreview>>,
}

/// Which encoding of the preview.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Encoding {
    Png,
    Exr,
}

impl Previews {
    /// The preview of running job `job_id` (of `size`, PNG at `exposure`), or None while no
    /// task of it is done (or its tasks are one whole render, which previews nothing).
    pub async fn get(
        &self,
        queue: &Queue,
        job_id: i64,
        size: (u32, u32),
        exposure: f32,
        encoding: Encoding,
    ) -> Result<Option<Vec<u8>>, String> {
        let done = queue.done_tasks(job_id).await.map_err(|e| e.to_string())?;
        if done.is_empty() {
            return Ok(None);
        }
        let mut kept = self.kept.lock().await;
        let at = match kept.iter().position(|p| p.job_id == job_id) {
            Some(at) => at,
            None => {
                if kept.len() >= KEPT_JOBS {
                    kept.remove(0);
                }
                kept.push(JobPreview {
                    job_id,
                    merged: BTreeSet::new(),
                    partial: None,
                    png: Vec::new(),
                    exr: Vec::new(),
                });
                kept.len() - 1
            }
        };
        // The most recently previewed last.
        let mut job = kept.remove(at);
        let new: Vec<i32> = done
            .into_iter()
            .filter(|s| !job.merged.contains(s))
            .collect();
        if !new.is_empty() {
            let results = queue
                .done_results(job_id, &new)
                .await
                .map_err(|e| e.to_string())?;
            let partial = job.partial.take();
            let (partial, merged, png, exr) =
                tokio::task::spawn_blocking(move || add_results(partial, size, exposure, results))
                    .await
                    .map_err(|e| e.to_string())??;
            job.partial = partial;
            job.merged.extend(merged);
            (job.png, job.exr) = (png, exr);
        }
        let image = match encoding {
            Encoding::Png => job.png.clone(),
            Encoding::Exr => job.exr.clone(),
        };
        kept.push(job);
        Ok((!image.is_empty()).then_some(image))
    }
}

type Added = (Option<Partial>, Vec<i32>, Vec<u8>, Vec<u8>);

/// `partial` with `results` added, the seqs added, and the image encoded (nothing for a
/// whole render's result).
fn add_results(
    partial: Option<Partial>,
    (width, height): (u32, u32),
    exposure: f32,
    results: Vec<(i32, Unit, Vec<u8>)>,
) -> Result<Added, String> {
    let mut partial = partial;
    let mut merged = Vec::new();
    for (seq, unit, bytes) in results {
        merged.push(seq);
        let fresh = || match unit {
            Unit::Rows { .. } => Some(Partial::Rows(Image::new(width, height))),
            Unit::Passes { .. } => Some(Partial::Passes {
                sum: PassSum::new(width, height),
                passes: 0,
            }),
            Unit::Whole => None,
        };
        if partial.is_none() {
            partial = fresh();
        }
        if let Some(p) = &mut partial {
            p.add(unit, &bytes)?;
        }
    }
    let Some(p) = &partial else {
        return Ok((None, merged, Vec::new(), Vec::new()));
    };
    let image = p.image();
    let png = output::encode_png(&image, exposure).map_err(|e| e.to_string())?;
    let exr = output::encode_exr(&image).map_err(|e| e.to_string())?;
    Ok((partial, merged, png, exr))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn band(value: f32, width: u32, rows: u32) -> Vec<u8> {
        (0..width * rows * 3)
            .flat_map(|_| value.to_le_bytes())
            .collect()
    }

    #[test]
    fn the_bands_done_so_far_show_on_black() {
        let rows = Unit::Rows { first: 2, count: 2 };
        let results = vec![(1, rows, band(0.5, 2, 2))];
        let (partial, merged, png, exr) = add_results(None, (2, 4), 1.0, results).unwrap();
        assert_eq!(merged, [1]);
        let image = partial.as_ref().unwrap().image();
        assert_eq!(image.pixels[..4], [[0.0; 3]; 4]);
        assert_eq!(image.pixels[4..], [[0.5; 3]; 4]);
        assert!(png.starts_with(b"\x89PNG") && !exr.is_empty());
        // The next band adds to what was merged.
        let results = vec![(0, Unit::Rows { first: 0, count: 2 }, band(2.0, 2, 2))];
        let (partial, merged, _, _) = add_results(partial, (2, 4), 1.0, results).unwrap();
        assert_eq!(merged, [0]);
        let image = partial.unwrap().image();
        assert_eq!(image.pixels[..4], [[2.0; 3]; 4]);
        assert_eq!(image.pixels[4..], [[0.5; 3]; 4]);
    }

    #[test]
    fn a_whole_render_previews_nothing_and_a_band_outside_is_refused() {
        let results = vec![(0, Unit::Whole, band(1.0, 2, 4))];
        let (partial, merged, png, _) = add_results(None, (2, 4), 1.0, results).unwrap();
        assert!(partial.is_none() && png.is_empty());
        assert_eq!(merged, [0]);
        let outside = vec![(3, Unit::Rows { first: 3, count: 2 }, band(1.0, 2, 2))];
        assert!(add_results(None, (2, 4), 1.0, outside).is_err());
    }
}
