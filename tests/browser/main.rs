//! End-to-end tests of the gallery (web/) in a real browser: Debian's headless Chromium,
//! driven through chromedriver (WebDriver) with fantoccini, against a real `photonbox serve`.
//! They need the `chromium` and `chromium-driver` packages (`.ci/run` installs them) and fail,
//! rather than skip, without them. Screenshots go to `$PHOTONBOX_SCREENSHOTS` if set
//! (`PHOTONBOX_SCREENSHOTS=docs/screenshots cargo test --test browser` regenerates the
//! committed ones), else under the target directory, so a test run leaves the checkout clean.
//!
//! Layout: `driver.rs` (chromedriver and Chromium sessions), `page.rs` (waiting, typing,
//! screenshots, checks of the page), `one_user.rs` (submit, watch, compare, cancel, a phone's
//! width), `users.rs` (who sees which job, signing out).

#[path = "../server/harness.rs"]
#[allow(dead_code)] // the browser tests use the server half of the harness only
mod harness;

mod driver;
mod one_user;
mod page;
mod users;
