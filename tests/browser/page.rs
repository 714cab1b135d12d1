//! Helpers that drive the page as a user would, wait for it, and check it.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use fantoccini::elements::Element;
use fantoccini::key::Key;
use fantoccini::{Client, Locator};
use serde_json::{Value, json};

use crate::driver::Browser;

/// Run a script in the page and return its value.
pub async fn js(c: &Client, script: &str) -> Value {
    c.execute(script, vec![])
        .await
        .unwrap_or_else(|e| panic!("script failed: {e}\n{script}"))
}

/// Poll `script` (a JS expression) until it is truthy; its value. Fails after `secs`.
pub async fn wait_for(c: &Client, what: &str, script: &str, secs: u64) -> Value {
    let t0 = Instant::now();
    let body = format!("return ({script});");
    loop {
        let v = js(c, &body).await;
        let truthy = match &v {
            Value::Null => false,
            Value::Bool(b) => *b,
            Value::Number(n) => n.as_f64() != Some(0.0),
            Value::String(s) => !s.is_empty(),
            _ => true,
        };
        if truthy {
            return v;
        }
        if t0.elapsed() > Duration::from_secs(secs) {
            let state = js(c, "return document.body.innerText.slice(0, 2000);").await;
            panic!("timed out after {secs} s waiting for {what} ({script}); page: {state}");
        }
        tokio::time::sleep(Duration::from_millis(40)).await;
    }
}

pub async fn by_id(c: &Client, id: &str) -> Element {
    c.find(Locator::Id(id))
        .await
        .unwrap_or_else(|e| panic!("no #{id}: {e}"))
}

/// Click the element `css` selects.
pub async fn click_css(c: &Client, css: &str) {
    c.find(Locator::Css(css))
        .await
        .unwrap_or_else(|e| panic!("no {css}: {e}"))
        .click()
        .await
        .unwrap();
}

/// Type `value` into the input `id` (replacing what was there), as a user would.
pub async fn type_into(c: &Client, id: &str, value: &str) {
    let el = by_id(c, id).await;
    el.clear().await.unwrap();
    el.send_keys(value).await.unwrap();
}

pub async fn select(c: &Client, id: &str, value: &str) {
    by_id(c, id).await.select_by_value(value).await.unwrap();
}

/// Where screenshots go. Chromium's: `$PHOTONBOX_SCREENSHOTS` if set (relative to the crate's
/// root; `docs/screenshots` regenerates the committed ones), else a folder under the target
/// directory, so that `cargo test` leaves the checkout as it was. Firefox's: always under the
/// target directory, in `firefox/`, so the committed screenshots stay Chromium's.
fn screenshot_dir(browser: Browser) -> PathBuf {
    let under_target = Path::new(env!("CARGO_TARGET_TMPDIR")).join("screenshots");
    match (browser, std::env::var_os("PHOTONBOX_SCREENSHOTS")) {
        (Browser::Chromium, Some(dir)) => Path::new(env!("CARGO_MANIFEST_DIR")).join(dir),
        (Browser::Chromium, None) => under_target,
        (Browser::Firefox, _) => under_target.join("firefox"),
    }
}

/// Save `browser`'s window as `name` in its screenshot folder; fails unless a PNG of the
/// window's viewport size and some content was written there.
pub async fn screenshot(c: &Client, browser: Browser, name: &str) {
    let png = c.screenshot().await.unwrap();
    let dir = screenshot_dir(browser);
    std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("create {}: {e}", dir.display()));
    let path = dir.join(name);
    std::fs::write(&path, &png).unwrap_or_else(|e| panic!("write {}: {e}", path.display()));
    let written = std::fs::read(&path).unwrap_or_else(|e| panic!("read {}: {e}", path.display()));
    assert!(written == png, "{}: not what was written", path.display());
    assert_eq!(
        image::guess_format(&written).ok(),
        Some(image::ImageFormat::Png),
        "{}",
        path.display()
    );
    // A blank page compresses to a few kB; every screenshot here shows renders and text.
    assert!(
        written.len() > 10_000,
        "{}: only {} bytes",
        path.display(),
        written.len()
    );
    let img = image::load_from_memory(&written).unwrap();
    let viewport = js(c, "return [window.innerWidth, window.innerHeight];").await;
    assert_eq!(
        json!([img.width(), img.height()]),
        viewport,
        "{}: the picture against the window's viewport",
        path.display()
    );
}

/// Open a sign-in URL (`{base}/?token=...`, the admin's) and wait until the page says who
/// is signed in and has loaded the built-in scenes.
pub async fn sign_in_as_admin(c: &Client, url: &str) {
    c.goto(url).await.unwrap();
    wait_for(
        c,
        "signed in as admin",
        "document.getElementById('me').textContent.includes('admin')",
        10,
    )
    .await;
    wait_for(
        c,
        "the built-in scenes",
        "document.querySelectorAll('#scene-name option').length >= 6",
        10,
    )
    .await;
}

/// The job id of the job page the browser is on.
pub async fn job_id_in_url(c: &Client) -> i64 {
    let hash = wait_for(
        c,
        "the job page after submitting",
        "location.hash.startsWith('#/job/') && location.hash",
        20,
    )
    .await;
    hash.as_str().unwrap()["#/job/".len()..].parse().unwrap()
}

/// Submit the form as it is filled, by keyboard (Enter on the submit button); the new id.
pub async fn submit_form(c: &Client) -> i64 {
    by_id(c, "submit")
        .await
        .send_keys(&Key::Enter.to_string())
        .await
        .unwrap();
    job_id_in_url(c).await
}

/// Fill the form for a tiny job of the Cornell box.
pub async fn fill_small(c: &Client, integrator: &str, size: u32, public: bool) {
    select(c, "scene-name", "cornell").await;
    select(c, "integrator", integrator).await;
    if integrator != "raytrace" {
        type_into(c, "photons", "4000").await;
        type_into(c, "caustic-photons", "2000").await;
        type_into(c, "k", "10").await;
        type_into(c, "gather-rays", "0").await;
    }
    type_into(c, "spp", "1").await;
    type_into(c, "width", &size.to_string()).await;
    type_into(c, "height", &size.to_string()).await;
    let checked = js(c, "return document.getElementById('public').checked;").await;
    if checked != json!(public) {
        by_id(c, "public").await.click().await.unwrap();
    }
}

pub async fn goto_gallery(c: &Client) {
    js(c, "location.hash = '#/';").await;
    wait_for(
        c,
        "the gallery",
        "!document.getElementById('view-gallery').hidden",
        10,
    )
    .await;
}

/// Ids on the gallery's cards, in page order.
pub async fn gallery_ids(c: &Client) -> Vec<i64> {
    let v = js(
        c,
        "return [...document.querySelectorAll('#gallery > li')].map(li => Number(li.dataset.jobId));",
    )
    .await;
    serde_json::from_value(v).unwrap()
}

/// Form controls without a label, images without alt text.
pub async fn accessibility_problems(c: &Client) -> Value {
    js(
        c,
        "const bad = [];
         for (const el of document.querySelectorAll('input, select, textarea')) {
           if (el.type !== 'hidden' && el.labels.length === 0 && !el.getAttribute('aria-label'))
             bad.push('unlabelled ' + (el.id || el.name || el.outerHTML.slice(0, 60)));
         }
         for (const img of document.querySelectorAll('img')) {
           if (!img.hidden && img.getAttribute('src') && !img.alt) bad.push('no alt: ' + (img.id || img.className));
         }
         return bad;",
    )
    .await
}

/// The page does not scroll sideways at this window size.
pub async fn assert_fits_width(c: &Client, what: &str) {
    let v = js(
        c,
        "const wide = [...document.querySelectorAll('body *')]
           .filter(e => e.getBoundingClientRect().right > window.innerWidth + 0.5)
           .map(e => e.tagName + '#' + e.id + '.' + e.className).slice(0, 8);
         return [document.documentElement.scrollWidth, window.innerWidth, wide];",
    )
    .await;
    let (scroll, inner) = (v[0].as_i64().unwrap(), v[1].as_i64().unwrap());
    assert!(
        scroll <= inner,
        "{what}: the page is {scroll}px wide in a {inner}px window; too wide: {}",
        v[2]
    );
}
