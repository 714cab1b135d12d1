//! End-to-end tests of the gallery (web/) in real browsers, against a real `photonbox serve`:
//! every test runs twice, as `<test>::chromium` (Debian's headless Chromium through
//! chromedriver) and `<test>::firefox` (Debian's headless Firefox ESR through geckodriver),
//! driven over WebDriver with fantoccini and asserting the same things in both.
//! They need the `chromium`, `chromium-driver` and `firefox-esr` packages and geckodriver
//! (`cargo install geckodriver --locked`: Debian has none); `.ci/run` installs them. Without
//! them the tests fail, rather than skip. `$CHROMEDRIVER`, `$CHROMIUM`, `$GECKODRIVER` and
//! `$FIREFOX` override the programs found on PATH.
//!
//! Chromium's screenshots go to `$PHOTONBOX_SCREENSHOTS` if set
//! (`PHOTONBOX_SCREENSHOTS=docs/screenshots cargo test --test browser` regenerates the
//! committed ones), else under the target directory, so a test run leaves the checkout clean;
//! Firefox's always go under the target directory, in `screenshots/firefox/`.
//!
//! Layout: `driver.rs` (the two browsers, their WebDriver servers and sessions), `page.rs`
//! (waiting, typing, screenshots, checks of the page), `one_user.rs` (submit, watch, compare,
//! cancel, a phone's width), `users.rs` (who sees which job, signing out), `farm.rs` (the
//! gallery on a farm: an API instance and a worker on PostgreSQL).

/// The tests `$body::chromium` and `$body::firefox` for an `async fn $body(Browser)`.
macro_rules! in_each_browser {
    ($body:ident) => {
        mod $body {
            use crate::driver::Browser;

            #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
            async fn chromium() {
                super::$body(Browser::Chromium).await;
            }

            #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
            async fn firefox() {
                super::$body(Browser::Firefox).await;
            }
        }
    };
}

#[path = "../server/harness.rs"]
#[allow(dead_code)] // the browser tests use the server half of the harness only
mod harness;

#[path = "../farm/pg.rs"]
#[allow(dead_code)] // the gallery on a farm needs a store, not the benchmark's clusters
mod pg;

mod driver;
mod farm;
mod one_user;
mod page;
mod users;
