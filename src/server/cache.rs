//! The photon-map cache. Photon maps do not depend on the camera, so jobs that differ only
//! in camera, resolution, k, spp or exposure share them, across users (key: [`cache_key`]).
//! A job reaches it through [`CachedMaps`], the engine's `MapSource` for one job.
//! Least-recently-used eviction within a byte budget; maps a render holds (an `Arc` clone
//! outside the cache) are never evicted from under it. Two jobs missing the same key at once
//! trace it once: the second waits for the first.

use std::collections::{HashMap, HashSet};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration;

use crate::render::photon::PhotonParams;
use crate::render::{Cancelled, MapRequest, MapSource, PhotonMaps, SuppliedMaps};

/// Whether a job's maps came from the cache.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CacheOutcome {
    Hit,
    Miss,
    /// The job needs no photon maps (`raytrace`).
    NotNeeded,
}

impl CacheOutcome {
    pub fn as_str(self) -> &'static str {
        match self {
            CacheOutcome::Hit => "hit",
            CacheOutcome::Miss => "miss",
            CacheOutcome::NotNeeded => "not_needed",
        }
    }
}

struct Entry {
    maps: Arc<PhotonMaps>,
    bytes: u64,
    last_used: u64,
}

#[derive(Default)]
struct Inner {
    entries: HashMap<String, Entry>,
    building: HashSet<String>,
    tick: u64,
}

pub struct MapCache {
    budget: u64,
    inner: Mutex<Inner>,
    built: Condvar,
    pub hits: AtomicU64,
    pub misses: AtomicU64,
}

impl MapCache {
    pub fn new(budget_bytes: u64) -> MapCache {
        MapCache {
            budget: budget_bytes,
            inner: Mutex::new(Inner::default()),
            built: Condvar::new(),
            hits: AtomicU64::new(0),
            misses: AtomicU64::new(0),
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Inner> {
        self.inner.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The maps for `key`: cached, or made by `build` (and cached if they fit the budget).
    pub fn get_or_build(
        &self,
        key: &str,
        cancel: &AtomicBool,
        build: impl FnOnce() -> Result<PhotonMaps, Cancelled>,
    ) -> Result<(Arc<PhotonMaps>, CacheOutcome), Cancelled> {
        let mut inner = self.lock();
        loop {
            inner.tick += 1;
            let tick = inner.tick;
            if let Some(e) = inner.entries.get_mut(key) {
                e.last_used = tick;
                self.hits.fetch_add(1, Ordering::Relaxed);
                return Ok((e.maps.clone(), CacheOutcome::Hit));
            }
            if !inner.building.contains(key) {
                break;
            }
            if cancel.load(Ordering::Relaxed) {
                return Err(Cancelled);
            }
            inner = self
                .built
                .wait_timeout(inner, Duration::from_millis(100))
                .unwrap_or_else(|e| e.into_inner())
                .0;
        }
        inner.building.insert(key.to_string());
        drop(inner);
        self.misses.fetch_add(1, Ordering::Relaxed);
        let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(build));
        let mut inner = self.lock();
        inner.building.remove(key);
        self.built.notify_all();
        let maps = match result {
            Ok(Ok(maps)) => Arc::new(maps),
            Ok(Err(c)) => return Err(c),
            Err(panic) => {
                drop(inner);
                std::panic::resume_unwind(panic)
            }
        };
        let bytes = maps.bytes() as u64;
        if bytes <= self.budget {
            inner.tick += 1;
            let last_used = inner.tick;
            inner.entries.insert(
                key.to_string(),
                Entry {
                    maps: maps.clone(),
                    bytes,
                    last_used,
                },
            );
            Self::evict(&mut inner, self.budget);
        }
        Ok((maps, CacheOutcome::Miss))
    }

    /// Drop least-recently-used entries nobody holds until the total fits the budget.
    fn evict(inner: &mut Inner, budget: u64) {
        loop {
            let total: u64 = inner.entries.values().map(|e| e.bytes).sum();
            if total <= budget {
                return;
            }
            let victim = inner
                .entries
                .iter()
                .filter(|(_, e)| Arc::strong_count(&e.maps) == 1)
                .min_by_key(|(_, e)| e.last_used)
                .map(|(k, _)| k.clone());
            match victim {
                Some(k) => {
                    inner.entries.remove(&k);
                }
                None => return, // everything left is in use
            }
        }
    }

    pub fn bytes(&self) -> u64 {
        self.lock().entries.values().map(|e| e.bytes).sum()
    }
}

/// The photon-map cache key: a content hash of the scene without its camera (see
/// `scenes::ResolvedScene::without_camera`), the parameters that shape the maps, and the
/// renderer's version.
pub fn cache_key(scene_without_camera: &str, photon_params: &PhotonParams) -> String {
    let text = format!(
        "photonbox {}\n{}\n{:?}",
        env!("CARGO_PKG_VERSION"),
        scene_without_camera,
        photon_params
    );
    super::auth::sha256_hex(text.as_bytes())
}

/// One job's photon maps through the cache: what the engine asks for, and what came of it
/// (STATS.json's `cache`).
pub struct CachedMaps<'a> {
    pub cache: &'a MapCache,
    /// The job's scene without its camera (its hash).
    pub scene_without_camera: &'a str,
    pub cancel: &'a AtomicBool,
    /// The outcome and key of the last lookup (none: the job needed no maps).
    pub used: Mutex<Option<(CacheOutcome, String)>>,
}

impl MapSource for CachedMaps<'_> {
    fn photon_maps(&self, want: &MapRequest) -> Result<SuppliedMaps, Cancelled> {
        let key = cache_key(self.scene_without_camera, want.params);
        let (maps, outcome) = self
            .cache
            .get_or_build(&key, self.cancel, || want.trace())?;
        *self.used.lock().unwrap_or_else(|e| e.into_inner()) = Some((outcome, key));
        let traced = outcome == CacheOutcome::Miss;
        Ok(SuppliedMaps { maps, traced })
    }
}
