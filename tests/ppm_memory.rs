//! Memory of a progressive render does not grow with its passes (issue 4, acceptance 1):
//! only one pass's photon maps exist at a time. Measured by a counting global allocator
//! (this test binary's own), as the peak of live heap bytes.

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use photonbox::render::{Control, render};
use photonbox::spec::{PhotonMapping, PhotonStore, Progressive, RenderSpec, Stop};

struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            let live = LIVE.fetch_add(layout.size(), Ordering::Relaxed) + layout.size();
            PEAK.fetch_max(live, Ordering::Relaxed);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
    }
}

#[global_allocator]
static ALLOC: Counting = Counting;

const SCENE: &str = r#"{
    "camera": {"position": [0, 2, 4], "look_at": [0, 0.5, 0], "up": [0, 1, 0], "fov": 45,
               "width": 64, "height": 48},
    "materials": {"floor": {"type": "diffuse", "albedo": [0.7, 0.7, 0.7]},
                  "glass": {"type": "dielectric", "ior": 1.5}},
    "objects": [{"type": "quad", "material": "floor", "corner": [-5, 0, 5],
                 "edge_u": [10, 0, 0], "edge_v": [0, 0, -10]},
                {"type": "sphere", "material": "glass", "center": [0, 0.6, 0], "radius": 0.5}],
    "lights": [{"type": "point", "position": [0, 3, 0], "power": [200, 200, 200]}]
}"#;

/// Peak live heap bytes during a ppm render of `passes` passes, above what was live before.
fn peak_bytes(passes: u32) -> usize {
    let scene = common::scene(SCENE);
    let params = RenderSpec::ppm(Progressive {
        pass: PhotonMapping {
            photons: 50_000,
            caustic_photons: 50_000,
            // Store every hit, so that the maps (not the film) dominate the memory.
            photon_store: PhotonStore::All,
            ..PhotonMapping::PPM_PASS
        },
        stop: Stop::after(passes),
        ..Progressive::DEFAULT
    });
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap();
    let base = LIVE.load(Ordering::Relaxed);
    PEAK.store(base, Ordering::Relaxed);
    let out = pool.install(|| render(&scene, &params, &Control::none()).unwrap());
    assert_eq!(out.stats.ppm.as_ref().map(|p| p.passes), Some(passes));
    PEAK.load(Ordering::Relaxed) - base
}

#[test]
fn memory_does_not_grow_with_passes() {
    let two = peak_bytes(2);
    let twenty = peak_bytes(20);
    eprintln!("peak heap: 2 passes {two} B, 20 passes {twenty} B");
    // One pass's maps alone are megabytes: ten times the passes within 15%.
    assert!(two > 1 << 20, "{two}");
    assert!(
        (twenty as f64) < 1.15 * two as f64,
        "20 passes peak at {twenty} B, 2 passes at {two} B"
    );
}
