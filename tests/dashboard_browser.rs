//! The dashboard in a real headless Chromium (through chromedriver and the `fantoccini`
//! WebDriver client): `gelgrip run` on the simulated tennis ball serves the page; the live
//! views update; clicking Grasp leads to a grasped state; a screenshot is saved
//! (`$GELGRIP_SCREENSHOT`, else `dashboard.png` under the build's tmp dir).

use std::time::{Duration, Instant};

use fantoccini::Locator;

mod common;
use common::browser::{chromium, start_chromedriver, text, wait_for};
use common::server::{Start, post, start_gelgrip, start_gelgrip_with};

/// A headless Chromium session on the page at `url`, once its `sensors` tiles are there.
async fn open_page(webdriver: &str, url: &str, sensors: usize) -> fantoccini::Client {
    let client = chromium(webdriver).await;
    client.goto(url).await.expect("the page loads");
    // The hand layout: one tile per sensor, each with its camera view.
    wait_for(Duration::from_secs(20), "the sensor tiles", || async {
        let tiles = client.find_all(Locator::Css(".sensor")).await.ok()?;
        (tiles.len() == sensors).then_some(())
    })
    .await;
    client
}

/// Every camera view of the page shows a frame.
async fn cameras_show(client: &fantoccini::Client, sensors: u64) {
    wait_for(Duration::from_secs(30), "camera frames", || async {
        let v = client
            .execute(
                "return Array.from(document.querySelectorAll('.views img.camera')).filter(i => i.naturalWidth > 0).length",
                vec![],
            )
            .await
            .ok()?;
        (v.as_u64()? == sensors).then_some(())
    })
    .await;
}

#[tokio::test]
#[ignore = "needs chromium: run scripts/test"]
async fn a_page_opened_mid_task_starts_with_the_last_30_seconds() {
    let (_gelgrip, url) = start_gelgrip(&["--scene", "configs/scenes/screwdriver.toml"]);
    let (status, body) = post(&url, "/api/task", r#"{"name": "screwdriver"}"#);
    assert_eq!(status, 200, "{body}");
    tokio::time::sleep(Duration::from_secs(20)).await;
    let (_driver, webdriver) = start_chromedriver();
    let client = open_page(&webdriver, &url, 7).await;
    // Each sensor's signal in the chart's data, as soon as the page has its first state:
    // the span of run time it covers.
    let spans: Vec<f64> = wait_for(Duration::from_secs(10), "the chart's data", || async {
        let v = client
            .execute(
                "if (typeof history === 'undefined' || !history.length) return null; \
                 const n = history[history.length - 1][1].length; \
                 return Array.from({length: n}, (_, i) => { \
                   const t = history.filter(h => Number.isFinite(h[1][i])).map(h => h[0]); \
                   return t.length ? t[t.length - 1] - t[0] : 0; });",
                vec![],
            )
            .await
            .ok()?;
        serde_json::from_value(v).ok()
    })
    .await;
    eprintln!("seconds of each signal in the chart on opening: {spans:?}");
    assert_eq!(spans.len(), 7, "{spans:?}");
    assert!(
        spans.iter().all(|s| *s >= 15.0),
        "at least 15 s of every signal: {spans:?}"
    );
    let task = text(&client, "#taskstate").await;
    assert!(task.contains("screwdriver"), "{task}");
    client.close().await.expect("session closed");
}

#[tokio::test]
#[ignore = "needs chromium: run scripts/test"]
async fn sixteen_sensors_show_up_live() {
    let (_gelgrip, url) = start_gelgrip(&["--config", "tests/configs/five-finger.toml"]);
    let (_driver, webdriver) = start_chromedriver();
    let client = open_page(&webdriver, &url, 16).await;
    cameras_show(&client, 16).await;
    let ids = text(&client, "#hand").await;
    assert!(ids.contains("f5.proximal") && ids.contains("palm"), "{ids}");
    client.close().await.expect("session closed");
}

#[tokio::test]
#[ignore = "needs chromium: run scripts/test"]
async fn the_dashboard_shows_live_views_and_grasps_on_a_click() {
    // A new user's first run: the default config (its dashboard run opens on the tennis
    // ball) with an empty calibration cache, and a browser with a fresh profile.
    let cache = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("gelgrip-fresh-cache-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&cache);
    let (_gelgrip, url) = start_gelgrip_with(&Start::default(), &cache, &[]);
    let (_driver, webdriver) = start_chromedriver();
    let client = open_page(&webdriver, &url, 7).await;
    // Live: the run clock in the header moves, and the camera images have pixels.
    let first = wait_for(Duration::from_secs(20), "the state", || async {
        let t = text(&client, "#run").await;
        t.contains(" s ·").then_some(t)
    })
    .await;
    wait_for(Duration::from_secs(10), "a newer state", || async {
        let t = text(&client, "#run").await;
        (t != first && !t.is_empty()).then_some(())
    })
    .await;
    cameras_show(&client, 7).await;

    let src = || async {
        client
            .execute(
                "return document.querySelector('.views img.camera').src",
                vec![],
            )
            .await
            .ok()
            .and_then(|v| v.as_str().map(str::to_string))
    };
    let before = src().await;
    tokio::time::sleep(Duration::from_millis(500)).await;
    assert_ne!(src().await, before, "the camera views follow new frames");

    // Grasp: the request resolves grasped, and the fingers hold. A machine that stalls the
    // run for 500 ms trips the watchdog (the grasp resolves `watchdog`, the fingers hold,
    // and the next set hands control back): that is the product working, so the page gets
    // one more try, and says so. Any other outcome fails.
    // The button starts a grasp goal and the page follows its progress, then its result,
    // within 20 s of the click.
    let mut result = String::new();
    for attempt in 1..=2 {
        client
            .find(Locator::Id("grasp"))
            .await
            .expect("the Grasp button")
            .click()
            .await
            .expect("click");
        let clicked = Instant::now();
        let progress = std::cell::Cell::new(false);
        result = wait_for(Duration::from_secs(20), "the grasp's outcome", || {
            let (client, progress) = (&client, &progress);
            async move {
                let t = text(client, "#result").await;
                progress.set(progress.get() || t.contains("running · f1 "));
                t.contains("\"reason\"").then_some(t)
            }
        })
        .await;
        eprintln!(
            "attempt {attempt}: the grasp resolved {:.1} s after the click",
            clicked.elapsed().as_secs_f64()
        );
        assert!(
            progress.get(),
            "the page showed the grasp's progress per finger"
        );
        if !result.contains("\"reason\":\"watchdog\"") {
            break;
        }
        eprintln!("attempt {attempt}: the watchdog stopped the grasp: {result}");
    }
    assert!(result.contains("\"grasped\":true"), "{result}");
    wait_for(Duration::from_secs(10), "fingers holding", || async {
        let t = text(&client, "#fingers").await;
        (t.matches("hold").count() == 3).then_some(())
    })
    .await;
    let touched = client
        .find_all(Locator::Css(".sensor.touch"))
        .await
        .expect("tiles")
        .len();
    assert!(touched >= 3, "the contact shows on the tiles: {touched}");
    // A plain gel cannot tell slip: the page says so, and draws no shear arrow.
    let grasp = text(&client, "#grasp-state").await;
    assert!(grasp.starts_with("slip unknown"), "{grasp}");
    let arrows = client
        .find_all(Locator::Css("svg.shear:not([data-state=\"unknown\"])"))
        .await
        .expect("arrows")
        .len();
    assert_eq!(arrows, 0, "no shear arrow on a plain gel");
    // The chart's tick labels, as the user reads them: distinct, each with the unit.
    let labels: Vec<String> = wait_for(Duration::from_secs(5), "tick labels", || async {
        let v = client
            .execute(
                "return Array.from(document.querySelectorAll('#plot-y-axis .tick')).map(e => e.textContent)",
                vec![],
            )
            .await
            .ok()?;
        let labels: Vec<String> = serde_json::from_value(v).ok()?;
        (labels.len() >= 3).then_some(labels)
    })
    .await;
    let mut unique = labels.clone();
    unique.sort();
    unique.dedup();
    assert_eq!(unique.len(), labels.len(), "distinct: {labels:?}");
    assert!(
        labels.iter().all(|l| l.ends_with(" mm³")),
        "with the unit: {labels:?}"
    );
    // Let the depth and contact images refresh once more, then keep a screenshot.
    tokio::time::sleep(Duration::from_millis(1200)).await;
    let png = client.screenshot().await.expect("a screenshot");
    assert_eq!(&png[1..4], b"PNG");
    let out = std::env::var_os("GELGRIP_SCREENSHOT")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("dashboard.png"));
    std::fs::write(&out, png).expect("screenshot written");

    // The simulator's panel shows, and a task from the list runs to completion.
    let sim = text(&client, "#faults").await;
    assert!(sim.contains("scene tennis-ball"), "{sim}");
    let task = client
        .execute("return document.getElementById('task-name').value", vec![])
        .await
        .expect("the task list");
    assert_eq!(task.as_str(), Some("pick-and-release"));
    client
        .find(Locator::Id("task"))
        .await
        .expect("the Run task button")
        .click()
        .await
        .expect("click");
    let ended = wait_for(Duration::from_secs(40), "the task's end", || async {
        let t = text(&client, "#taskstate").await;
        t.contains("ended").then_some(t)
    })
    .await;
    assert!(ended.contains("(completed)"), "{ended}");
    client.close().await.expect("session closed");
}

/// On marker gels: an auto grasp clicked on the page settles, the page shows the settled
/// force and the grasp's slip state, each finger's slip, and a shear arrow on every sensor
/// view whose gel reads slip (issue 44, item 4).
#[tokio::test]
#[ignore = "needs chromium: run scripts/test"]
async fn an_auto_grasp_on_marker_gels_shows_slip_and_its_settled_force() {
    let (_gelgrip, url) = start_gelgrip(&[
        "--config",
        "configs/gelgripper-sim-markers.toml",
        "--scene",
        "configs/scenes/tennis-ball.toml",
    ]);
    let (_driver, webdriver) = start_chromedriver();
    let client = open_page(&webdriver, &url, 7).await;
    // The scene starts over (its table drops 6 s in), and the grasp is asked at once.
    let (status, body) = post(&url, "/api/sim/scene", r#"{"name": "tennis-ball"}"#);
    assert_eq!(status, 200, "{body}");
    for id in ["auto-force", "grasp"] {
        client
            .find(Locator::Id(id))
            .await
            .unwrap_or_else(|e| panic!("#{id}: {e}"))
            .click()
            .await
            .expect("click");
    }
    let result = wait_for(Duration::from_secs(30), "the grasp's outcome", || async {
        let t = text(&client, "#result").await;
        t.contains("\"reason\"").then_some(t)
    })
    .await;
    assert!(result.contains("\"grasped\":true"), "{result}");
    // The ball needs less than today's fixed 1.5 N (it settled at 0.36 N here, at 1.24 N in
    // a clean-clone CI run with a benchmark beside it: on the real clock the table's drop
    // can come during the squeeze, and the grip relaxes slowly).
    let settled_result_n = result
        .split("\"settled_force_n\":")
        .nth(1)
        .and_then(|t| t.split([',', '}']).next())
        .and_then(|n| n.parse::<f64>().ok())
        .unwrap_or_else(|| panic!("a settled force in {result}"));
    assert!((0.25..1.5).contains(&settled_result_n), "{result}");
    let grasp = wait_for(Duration::from_secs(10), "the settled force", || async {
        let t = text(&client, "#grasp-state").await;
        t.contains("settled").then_some(t)
    })
    .await;
    eprintln!("the page shows: {grasp}");
    let settled_n: f64 = grasp
        .split("settled ")
        .nth(1)
        .and_then(|t| t.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("a force in {grasp}"));
    assert!(
        (0.1..4.0).contains(&settled_n),
        "between the preload and max_force_n: {grasp}"
    );
    assert!(!grasp.starts_with("slip unknown"), "{grasp}");
    // Each finger on the ball reads its slip; the views with a known slip show an arrow.
    let fingers = text(&client, "#fingers").await;
    assert!(
        fingers.matches("none").count() + fingers.matches("incipient").count() >= 3,
        "{fingers}"
    );
    let arrows: Vec<(String, String, String)> = serde_json::from_value(
        client
            .execute(
                "return Array.from(document.querySelectorAll('svg.shear')) \
                   .filter(s => getComputedStyle(s).display !== 'none') \
                   .map(s => [s.dataset.state, s.querySelector('line').getAttribute('x2'), \
                              s.querySelector('line').getAttribute('y2')])",
                vec![],
            )
            .await
            .expect("the arrows"),
    )
    .expect("arrows as strings");
    eprintln!("shear arrows: {arrows:?}");
    assert!(arrows.len() >= 3, "{arrows:?}");
    for (state, x, y) in &arrows {
        assert!(["none", "incipient", "gross"].contains(&state.as_str()));
        let (x, y): (f64, f64) = (x.parse().expect("x2"), y.parse().expect("y2"));
        assert!(x.is_finite() && y.is_finite() && x.abs() <= 1.0 && y.abs() <= 0.75);
    }
    client.close().await.expect("session closed");
}

/// The chart's axes (issue 31, item 2): the page's `gelgripAxis.axisTicks` labels every
/// decade from 1e-3 to 1e3 mm³, odd spans and degenerate input with distinct labels that
/// end in the unit and read back within half a step; the live chart's y-axis labels, read
/// from the page beside the canvas, are distinct and end in " mm³".
#[tokio::test]
#[ignore = "needs chromium: run scripts/test"]
async fn the_chart_s_tick_labels_are_distinct_and_carry_the_unit() {
    let (_gelgrip, url) = start_gelgrip(&["--scene", "configs/scenes/tennis-ball.toml"]);
    let (_driver, webdriver) = start_chromedriver();
    let client = open_page(&webdriver, &url, 7).await;

    let check = |what: &str, ticks: &serde_json::Value| {
        let ticks: Vec<(f64, String)> = ticks
            .as_array()
            .unwrap_or_else(|| panic!("{what}: ticks {ticks}"))
            .iter()
            .map(|t| {
                let value = t["value"].as_f64();
                let label = t["label"].as_str().map(str::to_string);
                value
                    .zip(label)
                    .unwrap_or_else(|| panic!("{what}: tick {t}"))
            })
            .collect();
        assert!(ticks.len() >= 2, "{what}: {ticks:?}");
        let step = ticks[1].0 - ticks[0].0;
        assert!(step.is_finite() && step > 0.0, "{what}: {ticks:?}");
        for (value, label) in &ticks {
            let lower = label.to_lowercase();
            assert!(
                !lower.contains("nan") && !lower.contains("inf"),
                "{what}: {label}"
            );
            let number = label
                .strip_suffix(" mm³")
                .unwrap_or_else(|| panic!("{what}: {label} lacks the unit"));
            let read: f64 = number.parse().unwrap_or_else(|_| panic!("{what}: {label}"));
            assert!(
                (read - value).abs() <= step / 2.0,
                "{what}: {label} for {value}"
            );
        }
        let mut labels: Vec<&String> = ticks.iter().map(|t| &t.1).collect();
        labels.dedup();
        assert_eq!(
            labels.len(),
            ticks.len(),
            "{what}: labels repeat: {ticks:?}"
        );
        eprintln!("{what}: {labels:?}");
    };
    let mut ranges: Vec<(f64, f64)> = (-3..=3)
        .flat_map(|e| {
            let top = 10f64.powi(e);
            [(0.0, top), (0.0, 3.7 * top), (top, 1.2 * top), (-top, top)]
        })
        .collect();
    ranges.extend([
        (0.0, 0.37),
        (997.0, 1003.0),
        (0.0, 0.05),
        (0.0, 0.0),
        (5.0, 5.0),
    ]);
    for (lo, hi) in ranges {
        let ticks = client
            .execute(
                "return gelgripAxis.axisTicks(arguments[0], arguments[1], 'mm³', 5)",
                vec![serde_json::json!(lo), serde_json::json!(hi)],
            )
            .await
            .expect("axisTicks runs");
        check(&format!("{lo}..{hi}"), &ticks);
    }
    // Non-finite input does not pass through JSON: the page makes it.
    let degenerate = client
        .execute(
            "return [[NaN, NaN], [NaN, 1], [0, Infinity], [-Infinity, Infinity], [1, NaN]]
               .map(([lo, hi]) => gelgripAxis.axisTicks(lo, hi, 'mm³', 5))",
            vec![],
        )
        .await
        .expect("axisTicks runs");
    for (i, ticks) in degenerate.as_array().expect("a list").iter().enumerate() {
        check(&format!("degenerate case {i}"), ticks);
    }

    // The live chart: its y-axis labels as shown, beside the canvas and within its height.
    let labels: Vec<String> = wait_for(Duration::from_secs(30), "the chart's y axis", || async {
        let ticks = client
            .find_all(Locator::Css("#plot-y-axis .tick"))
            .await
            .ok()?;
        let mut labels = Vec::new();
        for t in ticks {
            labels.push(t.text().await.ok()?);
        }
        (labels.len() >= 2).then_some(labels)
    })
    .await;
    let mut distinct = labels.clone();
    distinct.dedup();
    assert_eq!(distinct, labels, "the y-axis labels repeat");
    assert!(labels.iter().all(|l| l.ends_with(" mm³")), "{labels:?}");
    let placed = client
        .execute(
            "const c = document.getElementById('plot').getBoundingClientRect();
             const ticks = Array.from(document.querySelectorAll('#plot-y-axis .tick'));
             return ticks.every((t) => { const r = t.getBoundingClientRect();
               return r.width > 0 && r.right <= c.left + 1 && r.top >= c.top - r.height && r.bottom <= c.bottom + r.height; })",
            vec![],
        )
        .await
        .expect("the ticks' boxes");
    assert_eq!(
        placed.as_bool(),
        Some(true),
        "y ticks beside the canvas: {labels:?}"
    );
    let x_axis = text(&client, "#plot-x-axis").await;
    assert!(
        x_axis.contains("-30 s") && x_axis.contains("0 s"),
        "{x_axis}"
    );
    eprintln!("live y axis: {labels:?}; x axis: {x_axis}");
    client.close().await.expect("session closed");
}
