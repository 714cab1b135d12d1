//! Two users side by side: each sees their own jobs and the public ones, and signing out
//! forgets the token.

use fantoccini::Client;
use serde_json::json;

use crate::driver::{Browser, Driver};
use crate::harness::Server;
use crate::page::{by_id, fill_small, gallery_ids, goto_gallery, js, submit_form, wait_for};

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

in_each_browser!(two_users_see_their_own_and_public_jobs);

async fn two_users_see_their_own_and_public_jobs(browser: Browser) {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(dir.path(), &[]);
    let (alice_token, bob_token) = (s.add_user("alice"), s.add_user("bob"));
    // One WebDriver server each: geckodriver serves one session at a time.
    let (alice_driver, bob_driver) = (Driver::start(browser), Driver::start(browser));
    let alice = signed_in(&alice_driver, &s, &alice_token, "alice").await;
    let bob = signed_in(&bob_driver, &s, &bob_token, "bob").await;

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
