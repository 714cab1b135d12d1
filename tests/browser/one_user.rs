//! One user through the whole gallery: sign in, the estimate, field errors, a progressive
//! job watched live, a photon job, the gallery, a comparison, a cancel, a phone's width.

use fantoccini::key::Key;
use serde_json::json;

use crate::driver::{Browser, Driver};
use crate::harness::Server;
use crate::page::{
    accessibility_problems, assert_fits_width, by_id, click_css, fill_small, gallery_ids,
    goto_gallery, js, screenshot, select, sign_in_as_admin, submit_form, type_into, wait_for,
};

in_each_browser!(submit_watch_compare);

async fn submit_watch_compare(browser: Browser) {
    let dir = tempfile::tempdir().unwrap();
    let s = Server::start(dir.path(), &[]);
    let driver = Driver::start(browser);
    let c = driver.session().await;

    // Sign in with the printed URL: the token is kept, and dropped from the address bar.
    sign_in_as_admin(&c, &s.sign_in).await;
    let url = c.current_url().await.unwrap();
    assert!(!url.as_str().contains("token"), "token left in {url}");
    assert_eq!(
        js(&c, "return localStorage.getItem('photonbox-token');").await,
        json!(s.admin)
    );
    assert_eq!(accessibility_problems(&c).await, json!([]));

    // The form's defaults are the server's spec's, for each integrator.
    let value = |id: &str| format!("return document.getElementById('{id}').value;");
    for (integrator, p) in [
        ("ppm", photonbox::spec::PhotonMapping::PPM_PASS),
        ("photon", photonbox::spec::PhotonMapping::PHOTON),
    ] {
        by_id(&c, "integrator")
            .await
            .select_by_value(integrator)
            .await
            .unwrap();
        for (id, want) in [
            ("photons", p.photons.to_string()),
            ("k", p.k.to_string()),
            ("gather-rays", p.gather_rays.to_string()),
            ("spp", p.spp.to_string()),
        ] {
            assert_eq!(js(&c, &value(id)).await, json!(want), "{integrator}: #{id}");
        }
    }

    // The estimate follows the settings: final costs more than draft.
    select(&c, "scene-name", "cornell").await;
    let estimate = "Number(document.getElementById('estimate').dataset.seconds)";
    click_css(&c, "[data-preset=draft]").await;
    let draft = wait_for(&c, "a draft estimate", estimate, 5).await;
    assert_eq!(
        js(&c, "return document.getElementById('width').value;").await,
        json!("192"),
        "draft: half the scene's 384 pixels"
    );
    click_css(&c, "[data-preset=final]").await;
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
    click_css(&c, "input[name=scene-source][value=custom]").await;
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
    click_css(&c, "input[name=scene-source][value=builtin]").await;

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
    screenshot(&c, browser, "job-mid-render.png").await;
    let p2 = wait_for(
        &c,
        "progress advancing",
        &format!("{progress} > {p1} && {progress}"),
        20,
    )
    .await;
    assert!(p2.as_f64().unwrap() > p1);
    // Done, and its final image shown (not a preview: the last one is replaced by the
    // final image after the stream ends).
    wait_for(
        &c,
        "the job done and its final image shown",
        "document.getElementById('job-progress-text').dataset.status === 'done' && \
         document.getElementById('job-image').naturalWidth > 0 && \
         !document.getElementById('job-image').alt.includes('latest preview')",
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
    screenshot(&c, browser, "job-stats.png").await;
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
    screenshot(&c, browser, "gallery.png").await;

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
    screenshot(&c, browser, "compare.png").await;

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
    assert!(
        long != photon && long != ppm,
        "a new job (ids are random, not a sequence)"
    );

    // A progressive job measured against the first one, chosen in the form: its page
    // charts the error against time and per pass, one point per pass.
    goto_gallery(&c).await;
    fill_small(&c, "ppm", 96, false).await;
    type_into(&c, "iterations", "6").await;
    wait_for(
        &c,
        "the reference choice",
        &format!("document.querySelector('#reference-job option[value=\"{ppm}\"]')"),
        10,
    )
    .await;
    select(&c, "reference-job", &ppm.to_string()).await;
    let measured = submit_form(&c).await;
    let points = |chart: &str, series: &str| {
        format!(
            "Number(document.querySelector('#{chart} polyline[data-series=\"{series}\"]') \
             ?.dataset.points)"
        )
    };
    let n = wait_for(
        &c,
        "the error charts",
        &format!(
            "document.getElementById('job-progress-text').dataset.status === 'done' \
             && {}",
            points("chart-error-time", "relmse")
        ),
        30,
    )
    .await;
    assert_eq!(n.as_f64(), Some(6.0), "one point per pass against time");
    for series in ["relmse", "block_err"] {
        let n = js(
            &c,
            &format!("return {};", points("chart-error-pass", series)),
        )
        .await;
        assert_eq!(n.as_f64(), Some(6.0), "{series} per pass");
    }
    let stats = js(&c, "return document.getElementById('job-stats').innerText;").await;
    assert!(
        stats
            .as_str()
            .unwrap()
            .contains(&format!("Error against the reference (job {ppm})")),
        "{stats}"
    );
    assert!(measured != long && measured != ppm, "a new job");
    js(
        &c,
        "document.getElementById('chart-error-pass').scrollIntoView({block: 'end'});",
    )
    .await;
    screenshot(&c, browser, "job-accuracy.png").await;
    assert_eq!(accessibility_problems(&c).await, json!([]));

    // A phone's width: nothing scrolls sideways.
    c.set_window_size(390, 844).await.unwrap();
    assert_eq!(
        js(&c, "return window.innerWidth;").await,
        json!(390),
        "the page is laid out at a phone's width"
    );
    goto_gallery(&c).await;
    wait_for(
        &c,
        "the cards",
        "document.querySelectorAll('#gallery > li').length === 4",
        10,
    )
    .await;
    assert_fits_width(&c, "gallery at 390px").await;
    screenshot(&c, browser, "gallery-phone.png").await;
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
