//! End-to-end tests of the gallery (web/) in a real browser: Debian's headless Chromium,
//! driven through chromedriver (WebDriver) with fantoccini, against a real `photonbox serve`.
//! They need the `chromium` and `chromium-driver` packages (`.ci/run` installs them) and fail,
//! rather than skip, without them. Screenshots go to docs/screenshots/.

#[path = "server/harness.rs"]
#[allow(dead_code)] // the browser tests use the server half of the harness only
mod harness;

use std::net::{TcpListener, TcpStream};
use std::os::unix::process::CommandExt;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use fantoccini::elements::Element;
use fantoccini::key::Key;
use fantoccini::{Client, ClientBuilder, Locator};
use harness::Server;
use serde_json::{Value, json};

/// A program on PATH (or the path in the environment variable `var`), or a clear failure.
fn find_program(var: &str, names: &[&str]) -> PathBuf {
    let candidates: Vec<PathBuf> = match std::env::var_os(var) {
        Some(p) => vec![PathBuf::from(p)],
        None => std::env::split_paths(&std::env::var_os("PATH").unwrap_or_default())
            .flat_map(|dir| names.iter().map(move |n| dir.join(n)))
            .collect(),
    };
    if let Some(p) = candidates.into_iter().find(|p| p.is_file()) {
        return p;
    }
    panic!(
        "{} not found (looked at ${var} if set, else on PATH): the browser tests need Debian's headless \
         Chromium and its WebDriver: `apt-get install -y chromium chromium-driver` \
         (.ci/run does this)",
        names.join(" / ")
    );
}

/// chromedriver on a free port, in a process group of its own so that dropping it also
/// ends the Chromium processes it started.
struct Driver {
    child: Child,
    url: String,
}

impl Driver {
    fn start() -> Driver {
        let chromedriver = find_program("CHROMEDRIVER", &["chromedriver"]);
        let port = TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let child = Command::new(&chromedriver)
            .arg(format!("--port={port}"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .process_group(0)
            .spawn()
            .unwrap_or_else(|e| panic!("start {}: {e}", chromedriver.display()));
        let t0 = Instant::now();
        while TcpStream::connect(("127.0.0.1", port)).is_err() {
            assert!(
                t0.elapsed() < Duration::from_secs(20),
                "chromedriver did not listen on port {port} within 20 s"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        Driver {
            child,
            url: format!("http://127.0.0.1:{port}"),
        }
    }

    /// A new headless Chromium session with a 1280x800 window.
    async fn session(&self) -> Client {
        let chromium = find_program("CHROMIUM", &["chromium", "chromium-browser"]);
        let caps = json!({
            "browserName": "chrome",
            "goog:chromeOptions": {
                "binary": chromium,
                "args": ["--headless=new", "--no-sandbox", "--disable-gpu",
                         "--disable-dev-shm-usage", "--window-size=1280,800",
                         "--hide-scrollbars", "--force-device-scale-factor=1"],
            },
        });
        let caps = match caps {
            Value::Object(m) => m,
            _ => unreachable!(),
        };
        ClientBuilder::new(hyper_util::client::legacy::connect::HttpConnector::new())
            .capabilities(caps)
            .connect(&self.url)
            .await
            .unwrap_or_else(|e| panic!("start a Chromium session through chromedriver: {e}"))
    }
}

impl Drop for Driver {
    fn drop(&mut self) {
        // SAFETY: signalling the process group of a child we started.
        unsafe {
            libc::kill(-(self.child.id() as i32), libc::SIGKILL);
        }
        let _ = self.child.wait();
    }
}

/// Run a script in the page and return its value.
async fn js(c: &Client, script: &str) -> Value {
    c.execute(script, vec![])
        .await
        .unwrap_or_else(|e| panic!("script failed: {e}\n{script}"))
}

/// Poll `script` (a JS expression) until it is truthy; its value. Fails after `secs`.
async fn wait_for(c: &Client, what: &str, script: &str, secs: u64) -> Value {
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

async fn by_id(c: &Client, id: &str) -> Element {
    c.find(Locator::Id(id))
        .await
        .unwrap_or_else(|e| panic!("no #{id}: {e}"))
}

/// Type `value` into the input `id` (replacing what was there), as a user would.
async fn type_into(c: &Client, id: &str, value: &str) {
    let el = by_id(c, id).await;
    el.clear().await.unwrap();
    el.send_keys(value).await.unwrap();
}

async fn select(c: &Client, id: &str, value: &str) {
    by_id(c, id).await.select_by_value(value).await.unwrap();
}

async fn screenshot(c: &Client, name: &str) {
    let png = c.screenshot().await.unwrap();
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("docs/screenshots");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join(name), &png).unwrap();
    let img = image::load_from_memory(&png).unwrap();
    assert!(
        img.width() >= 300,
        "{name}: {}x{}",
        img.width(),
        img.height()
    );
}

/// The job id of the job page the browser is on.
async fn job_id_in_url(c: &Client) -> i64 {
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
async fn submit_form(c: &Client) -> i64 {
    by_id(c, "submit")
        .await
        .send_keys(&Key::Enter.to_string())
        .await
        .unwrap();
    job_id_in_url(c).await
}

/// Fill the form for a tiny job of the Cornell box.
async fn fill_small(c: &Client, integrator: &str, size: u32, public: bool) {
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

async fn goto_gallery(c: &Client) {
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
async fn gallery_ids(c: &Client) -> Vec<i64> {
    let v = js(
        c,
        "return [...document.querySelectorAll('#gallery > li')].map(li => Number(li.dataset.jobId));",
    )
    .await;
    serde_json::from_value(v).unwrap()
}

/// Form controls without a label, images without alt text.
async fn accessibility_problems(c: &Client) -> Value {
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
async fn assert_fits_width(c: &Client, what: &str) {
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

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn submit_watch_compare_in_the_browser() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(dir.path(), &[]);
    let driver = Driver::start();
    let c = driver.session().await;

    // Sign in with the printed URL: the token is kept, and dropped from the address bar.
    c.goto(&s.sign_in).await.unwrap();
    wait_for(
        &c,
        "signed in as admin",
        "document.getElementById('me').textContent.includes('admin')",
        10,
    )
    .await;
    let url = c.current_url().await.unwrap();
    assert!(!url.as_str().contains("token"), "token left in {url}");
    assert_eq!(
        js(&c, "return localStorage.getItem('photonbox-token');").await,
        json!(s.admin)
    );
    wait_for(
        &c,
        "the built-in scenes",
        "document.querySelectorAll('#scene-name option').length >= 6",
        10,
    )
    .await;
    assert_eq!(accessibility_problems(&c).await, json!([]));

    // The estimate follows the settings: final costs more than draft.
    select(&c, "scene-name", "cornell").await;
    by_id(&c, "integrator")
        .await
        .select_by_value("photon")
        .await
        .unwrap();
    let estimate = "Number(document.getElementById('estimate').dataset.seconds)";
    c.find(Locator::Css("[data-preset=draft]"))
        .await
        .unwrap()
        .click()
        .await
        .unwrap();
    let draft = wait_for(&c, "a draft estimate", estimate, 5).await;
    assert_eq!(
        js(&c, "return document.getElementById('width').value;").await,
        json!("192"),
        "draft: half the scene's 384 pixels"
    );
    c.find(Locator::Css("[data-preset=final]"))
        .await
        .unwrap()
        .click()
        .await
        .unwrap();
    let fin = wait_for(&c, "a final estimate", estimate, 5).await;
    assert!(
        fin.as_f64().unwrap() > 10.0 * draft.as_f64().unwrap(),
        "final {fin} s vs draft {draft} s"
    );

    // A bad value comes back with its path and is shown next to that field.
    fill_small(&c, "photon", 32, false).await;
    type_into(&c, "k", "0").await;
    by_id(&c, "submit").await.click().await.unwrap();
    let err = wait_for(
        &c,
        "the k error",
        "document.getElementById('k-error').textContent",
        10,
    )
    .await;
    assert!(err.as_str().unwrap().starts_with("params.k"), "{err}");
    assert_eq!(
        js(
            &c,
            "return document.getElementById('k').getAttribute('aria-invalid');"
        )
        .await,
        json!("true")
    );
    // A pasted scene's error names its path under `scene`.
    c.find(Locator::Css("input[name=scene-source][value=custom]"))
        .await
        .unwrap()
        .click()
        .await
        .unwrap();
    type_into(&c, "scene-json", r#"{"camera": 3}"#).await;
    type_into(&c, "k", "10").await;
    by_id(&c, "submit").await.click().await.unwrap();
    let err = wait_for(
        &c,
        "the scene error",
        "document.getElementById('scene-json-error').textContent",
        10,
    )
    .await;
    assert!(err.as_str().unwrap().starts_with("scene"), "{err}");
    assert_eq!(
        js(&c, "return document.getElementById('k-error').textContent;").await,
        json!(""),
        "old errors are cleared"
    );
    c.find(Locator::Css("input[name=scene-source][value=builtin]"))
        .await
        .unwrap()
        .click()
        .await
        .unwrap();

    // A progressive job: the bar advances, previews appear and update, then it is done.
    fill_small(&c, "ppm", 96, true).await;
    type_into(&c, "photons", "20000").await;
    type_into(&c, "caustic-photons", "20000").await;
    type_into(&c, "iterations", "40").await;
    let ppm = submit_form(&c).await;
    let progress = "document.getElementById('job-progress').value";
    let p1 = wait_for(
        &c,
        "progress under way",
        &format!("{progress} > 0 && {progress} < 0.5 && {progress}"),
        20,
    )
    .await
    .as_f64()
    .unwrap();
    wait_for(
        &c,
        "a preview while running",
        "document.getElementById('job-image').naturalWidth > 0 \
         && document.getElementById('job-progress').dataset.status === 'running'",
        20,
    )
    .await;
    select(&c, "job-zoom", "2").await;
    assert_eq!(
        js(
            &c,
            "return document.getElementById('job-image').style.width;"
        )
        .await,
        json!("192px"),
        "2x zoom of the 96-pixel image"
    );
    screenshot(&c, "job-mid-render.png").await;
    let p2 = wait_for(
        &c,
        "progress advancing",
        &format!("{progress} > {p1} && {progress}"),
        20,
    )
    .await;
    assert!(p2.as_f64().unwrap() > p1);
    wait_for(
        &c,
        "the job done",
        "document.getElementById('job-progress-text').dataset.status === 'done'",
        60,
    )
    .await;
    let img = js(
        &c,
        "const i = document.getElementById('job-image'); \
         return [i.naturalWidth, i.naturalHeight, Number(i.dataset.loads), i.alt, \
                 document.getElementById('job-progress').value];",
    )
    .await;
    assert_eq!((img[0].as_i64(), img[1].as_i64()), (Some(96), Some(96)));
    assert!(
        img[2].as_i64().unwrap() >= 2,
        "the image updated with previews: {img}"
    );
    assert!(img[3].as_str().unwrap().contains("cornell"), "{img}");
    assert_eq!(img[4].as_f64(), Some(1.0));
    let stats = wait_for(
        &c,
        "the stats",
        "document.getElementById('job-stats').innerText.includes('Effects simulated') \
         && document.getElementById('job-stats').innerText",
        10,
    )
    .await;
    assert!(
        stats.as_str().unwrap().contains("Progressive passes"),
        "{stats}"
    );
    // The convergence chart: one point per pass, the radius shrinking (SVG y grows down).
    let radius = js(
        &c,
        "return document.querySelector('#job-stats polyline[data-series=\"global radius\"]')
           .getAttribute('points').split(' ').map(p => Number(p.split(',')[1]));",
    )
    .await;
    let ys: Vec<f64> = serde_json::from_value(radius).unwrap();
    assert_eq!(ys.len(), 40);
    assert!(ys.windows(2).all(|w| w[1] >= w[0]), "{ys:?}");
    assert!(ys[39] > ys[0], "{ys:?}");
    js(
        &c,
        "document.querySelector('#job-stats .charts').scrollIntoView({block: 'end'});",
    )
    .await;
    screenshot(&c, "job-stats.png").await;
    assert_eq!(accessibility_problems(&c).await, json!([]));

    // A photon-map job of the same view, to compare with.
    goto_gallery(&c).await;
    fill_small(&c, "photon", 96, false).await;
    type_into(&c, "photons", "50000").await;
    let photon = submit_form(&c).await;
    wait_for(
        &c,
        "the photon job done",
        "document.getElementById('job-progress-text').dataset.status === 'done' \
         && document.getElementById('job-image').naturalWidth === 96",
        60,
    )
    .await;

    // The gallery: newest first, thumbnails, live status.
    goto_gallery(&c).await;
    wait_for(
        &c,
        "two cards with thumbnails",
        "[...document.querySelectorAll('#gallery > li')].filter(li => \
           li.dataset.status === 'done' && li.querySelector('img.thumb').naturalWidth > 0).length === 2",
        20,
    )
    .await;
    assert_eq!(gallery_ids(&c).await, vec![photon, ppm]);
    let text = js(
        &c,
        "return document.querySelector('#gallery > li').innerText;",
    )
    .await;
    let text = text.as_str().unwrap();
    assert!(text.contains("cornell") && text.contains("photon") && text.contains("96x96"));
    assert_eq!(accessibility_problems(&c).await, json!([]));
    screenshot(&c, "gallery.png").await;

    // Compare the two from the job page; move the split by keyboard.
    js(&c, &format!("location.hash = '#/job/{ppm}';")).await;
    wait_for(
        &c,
        "the compare choice",
        &format!("document.querySelector('#job-compare-with option[value=\"{photon}\"]')"),
        10,
    )
    .await;
    select(&c, "job-compare-with", &photon.to_string()).await;
    by_id(&c, "job-compare").await.click().await.unwrap();
    wait_for(
        &c,
        "both images in the comparison",
        "document.getElementById('compare-img-a').naturalWidth === 96 \
         && document.getElementById('compare-img-b').naturalWidth === 96",
        10,
    )
    .await;
    assert_eq!(
        js(&c, "return location.hash;").await,
        json!(format!("#/compare/{ppm}/{photon}"))
    );
    select(&c, "compare-zoom", "4").await;
    let slider = by_id(&c, "compare-split").await;
    for _ in 0..15 {
        slider.send_keys(&Key::Left.to_string()).await.unwrap();
    }
    let clip = js(
        &c,
        "return [document.getElementById('compare-split').value, \
                 document.getElementById('compare-img-a').style.clipPath];",
    )
    .await;
    assert_eq!(clip, json!(["35", "inset(0px 65% 0px 0px)"]));
    assert_eq!(accessibility_problems(&c).await, json!([]));
    screenshot(&c, "compare.png").await;

    // Cancel a long job from its page.
    goto_gallery(&c).await;
    fill_small(&c, "ppm", 64, false).await;
    type_into(&c, "iterations", "100000").await;
    let long = submit_form(&c).await;
    wait_for(
        &c,
        "the long job running",
        "document.getElementById('job-progress').value > 0",
        20,
    )
    .await;
    by_id(&c, "job-cancel").await.click().await.unwrap();
    wait_for(
        &c,
        "the job cancelled",
        "document.getElementById('job-progress-text').dataset.status === 'cancelled'",
        20,
    )
    .await;
    assert!(long > photon);

    // A phone's width: nothing scrolls sideways.
    c.set_window_size(390, 844).await.unwrap();
    goto_gallery(&c).await;
    wait_for(
        &c,
        "the cards",
        "document.querySelectorAll('#gallery > li').length === 3",
        10,
    )
    .await;
    assert_fits_width(&c, "gallery at 390px").await;
    screenshot(&c, "gallery-phone.png").await;
    js(&c, &format!("location.hash = '#/job/{ppm}';")).await;
    wait_for(
        &c,
        "the job page",
        "document.getElementById('job-image').naturalWidth === 96",
        10,
    )
    .await;
    assert_fits_width(&c, "job page at 390px").await;

    c.close().await.unwrap();
}

/// Sign in as `token` in a fresh session.
async fn signed_in(driver: &Driver, s: &Server, token: &str, name: &str) -> Client {
    let c = driver.session().await;
    c.goto(&format!("{}/?token={token}", s.base)).await.unwrap();
    wait_for(
        &c,
        "signed in",
        &format!("document.getElementById('me').textContent.includes('{name}')"),
        10,
    )
    .await;
    wait_for(
        &c,
        "the built-in scenes",
        "document.querySelectorAll('#scene-name option').length > 0",
        10,
    )
    .await;
    c
}

/// Submit a tiny raytrace job from the form; back to the gallery.
async fn submit_tiny(c: &Client, public: bool) -> i64 {
    goto_gallery(c).await;
    fill_small(c, "raytrace", 24, public).await;
    let id = submit_form(c).await;
    goto_gallery(c).await;
    id
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_users_see_their_own_and_public_jobs_only() {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(dir.path(), &[]);
    let (alice_token, bob_token) = (s.add_user("alice"), s.add_user("bob"));
    let driver = Driver::start();
    let alice = signed_in(&driver, &s, &alice_token, "alice").await;
    let bob = signed_in(&driver, &s, &bob_token, "bob").await;

    let alice_private = submit_tiny(&alice, false).await;
    let alice_public = submit_tiny(&alice, true).await;
    let bob_private = submit_tiny(&bob, false).await;
    let bob_public = submit_tiny(&bob, true).await;

    // Once a gallery shows the newest job, it was fetched after every job existed.
    let has = |id: i64| format!("document.querySelector('#gallery > li[data-job-id=\"{id}\"]')");
    wait_for(&alice, "bob's public job", &has(bob_public), 20).await;
    wait_for(&bob, "bob's last job", &has(bob_public), 20).await;
    assert_eq!(
        gallery_ids(&alice).await,
        vec![bob_public, alice_public, alice_private]
    );
    assert_eq!(
        gallery_ids(&bob).await,
        vec![bob_public, bob_private, alice_public]
    );
    let owner = js(
        &alice,
        &format!(
            "return document.querySelector('#gallery > li[data-job-id=\"{bob_public}\"] .owner').textContent;"
        ),
    )
    .await;
    assert_eq!(owner, json!("by bob · public"));

    // Bob's private job does not exist for alice, even by its address.
    js(&alice, &format!("location.hash = '#/job/{bob_private}';")).await;
    let err = wait_for(
        &alice,
        "the not-found message",
        "document.getElementById('job-error').textContent",
        10,
    )
    .await;
    assert_eq!(
        err,
        json!(format!("There is no job {bob_private} you may see."))
    );

    // Signing out forgets the token, also across a reload.
    by_id(&bob, "sign-out").await.click().await.unwrap();
    wait_for(
        &bob,
        "the sign-in form",
        "!document.getElementById('view-signin').hidden",
        10,
    )
    .await;
    assert_eq!(
        js(&bob, "return [localStorage.getItem('photonbox-token'), document.querySelectorAll('#gallery > li').length];").await,
        json!([null, 0])
    );
    bob.refresh().await.unwrap();
    wait_for(
        &bob,
        "the sign-in form after a reload",
        "!document.getElementById('view-signin').hidden \
         && document.getElementById('view-gallery').hidden",
        10,
    )
    .await;

    alice.close().await.unwrap();
    bob.close().await.unwrap();
}
