//! The dashboard in a real headless Chromium (through chromedriver and the `fantoccini`
//! WebDriver client): `gelgrip run` on the simulated tennis ball serves the page; the live
//! views update; clicking Grasp leads to a grasped state; a screenshot is saved
//! (`$GELGRIP_SCREENSHOT`, else `dashboard.png` under the build's tmp dir).

use std::os::unix::process::CommandExt;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use fantoccini::{ClientBuilder, Locator};

mod common;
use common::server::{Running, free_port, start_gelgrip};

fn start_chromedriver() -> (Running, String) {
    let port = free_port();
    let child = Command::new("chromedriver")
        .process_group(0)
        .arg(format!("--port={port}"))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("chromedriver starts (Debian chromium-driver)");
    let deadline = Instant::now() + Duration::from_secs(20);
    while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
        assert!(Instant::now() < deadline, "chromedriver is not listening");
        std::thread::sleep(Duration::from_millis(100));
    }
    (Running(child), format!("http://127.0.0.1:{port}"))
}

async fn text(client: &fantoccini::Client, css: &str) -> String {
    match client.find(Locator::Css(css)).await {
        Ok(e) => e.text().await.unwrap_or_default(),
        Err(_) => String::new(),
    }
}

/// Poll `check` until it returns `Some`, or fail with `what` after `timeout`.
async fn wait_for<T, F, Fut>(timeout: Duration, what: &str, mut check: F) -> T
where
    F: FnMut() -> Fut,
    Fut: std::future::Future<Output = Option<T>>,
{
    let deadline = Instant::now() + timeout;
    loop {
        if let Some(v) = check().await {
            return v;
        }
        assert!(Instant::now() < deadline, "timed out waiting for {what}");
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
}

/// A headless Chromium session on the page at `url`, once its `sensors` tiles are there.
async fn open_page(webdriver: &str, url: &str, sensors: usize) -> fantoccini::Client {
    let mut caps = serde_json::Map::new();
    caps.insert(
        "goog:chromeOptions".into(),
        serde_json::json!({
            "binary": "/usr/bin/chromium",
            "args": ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage", "--window-size=1400,1100"]
        }),
    );
    let client = ClientBuilder::new(hyper_util::client::legacy::connect::HttpConnector::new())
        .capabilities(caps)
        .connect(webdriver)
        .await
        .expect("a Chromium session");
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
    let (_gelgrip, url) = start_gelgrip(&["--scene", "configs/scenes/tennis-ball.toml"]);
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
    let mut result = String::new();
    for attempt in 1..=2 {
        client
            .find(Locator::Id("grasp"))
            .await
            .expect("the Grasp button")
            .click()
            .await
            .expect("click");
        result = wait_for(Duration::from_secs(60), "the grasp's outcome", || async {
            let t = text(&client, "#result").await;
            t.contains("\"reason\"").then_some(t)
        })
        .await;
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
