//! The gallery on a farm: `photonbox serve --store postgres://... --no-render` and one
//! `photonbox worker`, with PostgreSQL started in a temporary directory (as `tests/farm`
//! does). Sign in by the printed URL, submit a progressive job through the form, watch it
//! to its final image, find it in the gallery, and delete it from its page.

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};

use fantoccini::Client;
use serde_json::json;

use crate::driver::{Browser, Driver};
use crate::page::{
    accessibility_problems, click_css, fill_small, gallery_ids, goto_gallery, js, sign_in_as_admin,
    submit_form, wait_for,
};
use crate::pg::cluster;

const BIN: &str = env!("CARGO_BIN_EXE_photonbox");

/// A child process, killed when dropped.
struct Proc(Child);

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// An API instance on `store`: the process and the sign-in URL it printed.
fn start_api(store: &str) -> (Proc, String) {
    let mut child = Command::new(BIN)
        .args([
            "serve",
            "--addr",
            "127.0.0.1:0",
            "--no-render",
            "--store",
            store,
        ])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let sign_in = loop {
        let line = lines.next().expect("the API's output").unwrap();
        if let Some(url) = line.strip_prefix("photonbox: gallery (signed in as admin): ") {
            break url.to_string();
        }
    };
    std::thread::spawn(move || for _ in lines {});
    (Proc(child), sign_in)
}

fn start_worker(store: &str) -> Proc {
    let child = Command::new(BIN)
        .args(["worker", "--threads", "1", "--store", store, "--id", "w0"])
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    Proc(child)
}

async fn wait_done_with_image(c: &Client, size: u32) {
    wait_for(
        c,
        "the job done and its final image shown",
        &format!(
            "document.getElementById('job-progress-text').dataset.status === 'done' && \
             document.getElementById('job-image').naturalWidth === {size} && \
             !document.getElementById('job-image').alt.includes('latest preview')"
        ),
        60,
    )
    .await;
}

in_each_browser!(the_gallery_on_a_farm);

async fn the_gallery_on_a_farm(browser: Browser) {
    let store = cluster().fresh_db().await;
    let (_api, sign_in) = start_api(&store);
    let _worker = start_worker(&store);
    let driver = Driver::start(browser);
    let c = driver.session().await;

    sign_in_as_admin(&c, &sign_in).await;

    fill_small(&c, "ppm", 64, false).await;
    let id = submit_form(&c).await;
    wait_done_with_image(&c, 64).await;
    let status = js(
        &c,
        "return document.getElementById('job-summary').innerText;",
    )
    .await;
    assert!(status.as_str().unwrap().contains("yours"), "{status}");
    assert_eq!(accessibility_problems(&c).await, json!([]));

    goto_gallery(&c).await;
    wait_for(
        &c,
        "the job's card with its thumbnail",
        "[...document.querySelectorAll('#gallery > li')].some(li => \
           li.dataset.status === 'done' && li.querySelector('img.thumb').naturalWidth > 0)",
        20,
    )
    .await;
    assert_eq!(gallery_ids(&c).await, vec![id]);

    // Delete it from its page (the page asks first: say yes).
    js(&c, &format!("location.hash = '#/job/{id}';")).await;
    wait_done_with_image(&c, 64).await;
    js(&c, "window.confirm = () => true;").await;
    click_css(&c, "#job-cancel").await;
    wait_for(
        &c,
        "back in the gallery, the job gone",
        "!document.getElementById('view-gallery').hidden && \
         document.querySelectorAll('#gallery > li').length === 0",
        20,
    )
    .await;
    c.close().await.unwrap();
}
