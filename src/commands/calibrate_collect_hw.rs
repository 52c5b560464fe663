//! `gelgrip calibrate collect` on a hardware hub (`cdc`, `ch347` or their emulators, as
//! the config says): a press dataset of a real sensor, labelled as it is collected.
//!
//! The sensor's frames come through the configured hub and gate, as in a run. The user is
//! prompted on stderr (lines starting `> `) and answers on stdin:
//! 1. with the sensor untouched, Enter: [`BACKGROUND_FRAMES`] frames are averaged into
//!    `background.png`;
//! 2. for each press, the user presses the ball; the command waits for a contact, waits
//!    until [`SETTLE_FRAMES`] looks in a row (each at the mean of the last
//!    [`SETTLE_FRAMES`] frames) show the same circle, says why a contact it sees is not
//!    taken (too shallow, cut by the pad's edge, …), averages the next
//!    [`AVERAGE_FRAMES`] and labels that ([`detect`]); Enter keeps the
//!    press, `r` and Enter redoes it. A kept press is written (`press_NNN.png`, and
//!    `presses.csv` rewritten) at once. The next press must first be lifted off, or moved.
//!
//! SIGINT or stdin closing ends the session early: every press already kept stays on disk
//! and in `presses.csv`, and the command says how many (exit 0 on SIGINT, 1 when stdin
//! closed).
//!
//! Unless `--headless`, the calibration view is served too (`--http ADDR`, else
//! `[http] bind`; [`calibrate_collect_view`](super::calibrate_collect_view)): the live
//! difference image with the detected circle, the label or why a press is not usable, the
//! count kept, and Keep and Redo. A decision comes from stdin or from the page, whichever
//! answers first ([`Session::decide`]); the other prompt moves on.

use std::path::Path;
use std::pin::Pin;
use std::sync::Arc;
use std::time::Duration;

use anyhow::Context;
use tokio::sync::mpsc;

use gelgrip_controller::acquire::Acquisition;
use gelgrip_controller::clock::Clock;
use gelgrip_controller::config::AppConfig;
use gelgrip_plugins::calibrate::label::{ContactCircle, Rejection, detect};
use gelgrip_plugins::calibrate::sheet::difference_view;
use gelgrip_plugins::dataset::{DatasetInfo, Press, PressDataset, write_presses_csv};
use gelgrip_plugins::image::RgbImage;
use gelgrip_web::calibrate::{CollectStatus, CollectView, Decision, LabelView, Phase};

use crate::cli::{CollectArgs, UsageError};
use crate::commands::calibrate_collect_view::ViewServer;
use crate::commands::calibrate_force_hw::stdin_lines;
use gelgrip::wiring;
use gelgrip_controller::clock::ClockKind;

/// Frames averaged into the background.
pub const BACKGROUND_FRAMES: usize = 10;
/// Frames in a row showing the same circle before a press counts as settled.
pub const SETTLE_FRAMES: usize = 3;
/// Frames averaged into a press once it has settled.
pub const AVERAGE_FRAMES: usize = 5;
/// Two circles are the same when their centres are this close, px…
const SAME_CENTRE_PX: f64 = 1.0;
/// …and their radii within this share.
const SAME_RADIUS: f64 = 0.03;
/// Longest wait for one synchronized set before the hub counts as gone.
const SET_TIMEOUT: Duration = Duration::from_secs(5);

/// How the session ended early.
#[derive(Debug)]
enum Stop {
    Signal,
    StdinClosed,
    Failed(anyhow::Error),
}

impl From<anyhow::Error> for Stop {
    fn from(e: anyhow::Error) -> Self {
        Self::Failed(e)
    }
}

/// Collect `args.presses` presses of `args.sensor` through the configured hub.
pub async fn collect(args: &CollectArgs, config: &AppConfig) -> anyhow::Result<u8> {
    let id = args.sensor.as_str();
    let index = config.layout.index_of(id).ok_or_else(|| {
        UsageError(format!(
            "no sensor `{id}` in layout `{}`; sensors: {}",
            config.layout.name,
            config.layout.id_list()
        ))
    })?;
    let ball_mm = args.ball_mm.ok_or_else(|| {
        UsageError(
            "--ball-mm is required on a hardware hub: the diameter of the ball you press".into(),
        )
    })?;
    let mm_per_px = args
        .mm_per_px
        .unwrap_or(config.layout.sensors[index].mm_per_px);
    let info = DatasetInfo {
        ball_diameter_mm: ball_mm,
        mm_per_px,
    };
    let wanted = args.presses as usize;
    let view = CollectView::new(CollectStatus {
        sensor: id.to_string(),
        wanted,
        kept: 0,
        phase: Phase::Background,
        message: String::new(),
        attempt: None,
        label: None,
        rejection: None,
        image: 0,
        ball_mm,
        mm_per_px,
        out: args.out.display().to_string(),
    });
    let server = if args.headless {
        None
    } else {
        let bind = args.http.unwrap_or(config.http.bind);
        Some(ViewServer::start(config, bind, view.clone()).await?)
    };
    let clock = ClockKind::Real.new_clock();
    let acq = wiring::open_acquisition(config, &wiring::registry(), clock.clone())
        .await
        .with_context(|| format!("opening the {} hub", config.hub.transport))?;
    let mut s = Session {
        acq,
        index,
        clock,
        stdin: stdin_lines(),
        signal: Box::pin(crate::commands::run::shutdown_signal()),
        view,
        served: server.is_some(),
    };
    let mut kept = Vec::new();
    eprintln!(
        "calibrate collect on {id} through the {} hub: {wanted} presses of a {ball_mm} mm ball at {mm_per_px} mm/px into {}",
        config.hub.transport,
        args.out.display()
    );
    let outcome = session(&mut s, &args.out, &info, wanted, &mut kept).await;
    let n = kept.len();
    let place = args.out.display();
    let (phase, note) = match &outcome {
        Ok(()) => (Phase::Done, format!("{n} presses kept in {place}")),
        Err(Stop::Signal) => (Phase::Ended, format!("interrupted: {n} of {wanted} kept")),
        Err(Stop::StdinClosed) => (Phase::Ended, format!("stdin closed: {n} of {wanted} kept")),
        Err(Stop::Failed(e)) => (
            Phase::Ended,
            format!("failed ({e:#}): {n} of {wanted} kept"),
        ),
    };
    s.view.end(phase, note);
    if let Some(server) = server {
        server.shut_down().await;
    }
    match outcome {
        Ok(()) => {
            println!("{place}: {n} presses kept, ball {ball_mm} mm, {mm_per_px} mm/px");
            Ok(0)
        }
        Err(Stop::Signal) => {
            println!(
                "interrupted: {n} of {wanted} presses kept in {place} (presses.csv lists them)"
            );
            Ok(0)
        }
        Err(Stop::StdinClosed) => {
            println!(
                "stdin closed: {n} of {wanted} presses kept in {place} (presses.csv lists them)"
            );
            Ok(1)
        }
        Err(Stop::Failed(e)) => {
            eprintln!("{n} of {wanted} presses kept in {place} (presses.csv lists them)");
            Err(e)
        }
    }
}

async fn session(
    s: &mut Session,
    out: &Path,
    info: &DatasetInfo,
    wanted: usize,
    kept: &mut Vec<Press>,
) -> Result<(), Stop> {
    s.prompt_line("leave the sensor untouched, then press Enter")
        .await?;
    let background = average(&s.frames(BACKGROUND_FRAMES).await?)?;
    PressDataset::write_index(out, info, &background, &[]).map_err(anyhow::Error::from)?;
    s.show(&background, &background, None);
    let ball_radius_px = info.ball_diameter_mm / 2.0 / info.mm_per_px;
    let mut last: Option<ContactCircle> = None;
    let mut attempt = 0;
    while kept.len() < wanted {
        s.say(&format!(
            "press the ball on the sensor and hold it still (press {} of {wanted})",
            kept.len() + 1
        ));
        s.view.update(|v| v.phase = Phase::Pressing);
        let img = s.settled_press(&background, ball_radius_px, last).await?;
        let circle = match detect(&img, &background, ball_radius_px) {
            Ok(c) => c,
            Err(reason) => {
                eprintln!("  not usable: {reason}; lift the ball and press again");
                s.show(&img, &background, None);
                s.view.update(|v| {
                    v.label = None;
                    v.rejection = Some(reason.to_string());
                });
                last = None;
                continue;
            }
        };
        last = Some(circle);
        eprintln!(
            "  contact at ({:.1}, {:.1}) px, radius {:.1} px, score {:.2}",
            circle.center_x_px, circle.center_y_px, circle.contact_radius_px, circle.score
        );
        s.show(&img, &background, Some(circle));
        s.view.update(|v| {
            v.label = Some(label_view(&circle));
            v.rejection = None;
        });
        attempt += 1;
        let (decision, page) = s.decide(attempt).await?;
        if decision == Decision::Redo {
            eprintln!("  redo: lift the ball and press again");
            if let Some(page) = page {
                page.done(s.view.status());
            }
            continue;
        }
        let file = format!("press_{:03}.png", kept.len());
        img.write_png(&out.join(&file))
            .map_err(anyhow::Error::from)?;
        kept.push(Press {
            file,
            center_x_px: circle.center_x_px,
            center_y_px: circle.center_y_px,
            contact_radius_px: circle.contact_radius_px,
        });
        write_presses_csv(out, kept).map_err(anyhow::Error::from)?;
        eprintln!("  kept {} of {wanted}", kept.len());
        let n = kept.len();
        s.view.update(|v| v.kept = n);
        if let Some(page) = page {
            page.done(s.view.status());
        }
    }
    Ok(())
}

fn label_view(c: &ContactCircle) -> LabelView {
    LabelView {
        center_x_px: c.center_x_px,
        center_y_px: c.center_y_px,
        contact_radius_px: c.contact_radius_px,
        score: c.score,
    }
}

/// The live session: the hub's sets, stdin's lines and the shutdown signal.
struct Session {
    acq: Acquisition,
    index: usize,
    clock: std::sync::Arc<dyn Clock>,
    stdin: mpsc::Receiver<String>,
    signal: Pin<Box<dyn Future<Output = ()> + Send>>,
    /// What the calibration view shows, and its decisions.
    view: Arc<CollectView>,
    /// Whether the view is served (else no image is drawn for it).
    served: bool,
}

impl Session {
    /// Prompt `> step` on stderr and on the page.
    fn say(&self, step: &str) {
        eprintln!("> {step}");
        let step = step.to_string();
        self.view.update(|v| v.message = step);
    }

    /// Show `img`'s difference from `background`, with `circle`, on the page.
    fn show(&self, img: &RgbImage, background: &RgbImage, circle: Option<ContactCircle>) {
        if self.served {
            let d = difference_view(img, background, circle);
            self.view.set_image(d.width, d.height, d.data);
        }
    }

    /// Ask whether to keep press `attempt`, on stdin (Enter keeps, `r` redoes) and on the
    /// page at once; the first answer decides, and the other question is withdrawn. The
    /// page's answer is returned too, for the session to answer it once it has acted.
    async fn decide(
        &mut self,
        attempt: u64,
    ) -> Result<(Decision, Option<gelgrip_web::calibrate::PageAnswer>), Stop> {
        // Open on the page before the prompt, so that whoever reads the prompt can answer
        // on either.
        let mut page = self.view.ask(attempt);
        let on_page = if self.served {
            " (or Keep / Redo on the dashboard)"
        } else {
            ""
        };
        self.say(&format!(
            "keep it? Enter keeps it, `r` then Enter redoes it{on_page}"
        ));

        let mut page_open = true;
        loop {
            tokio::select! {
                line = self.stdin.recv() => {
                    let line = line.ok_or(Stop::StdinClosed)?;
                    if self.view.withdraw(attempt) || !page_open {
                        let d = if line.trim().eq_ignore_ascii_case("r") {
                            Decision::Redo
                        } else {
                            Decision::Keep
                        };
                        return Ok((d, None));
                    }
                    // The page claimed the press just before: its answer is on its way,
                    // and this line is spent.
                    if let Ok(answer) = (&mut page).await {
                        return Ok(page_decision(answer));
                    }
                    page_open = false;
                }
                answer = &mut page, if page_open => match answer {
                    Ok(answer) => return Ok(page_decision(answer)),
                    Err(_) => page_open = false,
                },
                () = &mut self.signal => return Err(Stop::Signal),
                step = self.acq.step() => { step.context("the hub, between presses")?; }
            }
        }
    }

    /// Prompt `> step` and wait for a line, keeping the hub's sets flowing meanwhile.
    async fn prompt_line(&mut self, step: &str) -> Result<String, Stop> {
        self.say(step);
        loop {
            tokio::select! {
                line = self.stdin.recv() => return line.ok_or(Stop::StdinClosed),
                () = &mut self.signal => return Err(Stop::Signal),
                step = self.acq.step() => { step.context("the hub, between presses")?; }
            }
        }
    }

    /// The sensor's next frame, decoded; stdin lines meanwhile are ignored.
    async fn frame(&mut self) -> Result<RgbImage, Stop> {
        loop {
            let deadline = self.clock.now_us() + SET_TIMEOUT.as_micros() as u64;
            let set = tokio::select! {
                set = self.acq.next_set_before(deadline) => set.context("the hub")?,
                () = &mut self.signal => return Err(Stop::Signal),
                line = self.stdin.recv() => {
                    if line.is_none() {
                        return Err(Stop::StdinClosed);
                    }
                    continue;
                }
            };
            let Some(set) = set else {
                return Err(Stop::Failed(anyhow::anyhow!(
                    "no synchronized set from the hub in {} s",
                    SET_TIMEOUT.as_secs()
                )));
            };
            let frame = set
                .frames
                .get(self.index)
                .context("a set without this sensor's frame")?;
            return Ok(
                RgbImage::from_jpeg("a frame", &frame.frame.jpeg).map_err(anyhow::Error::from)?
            );
        }
    }

    async fn frames(&mut self, n: usize) -> Result<Vec<RgbImage>, Stop> {
        let mut out = Vec::with_capacity(n);
        while out.len() < n {
            out.push(self.frame().await?);
        }
        Ok(out)
    }

    /// Wait for a contact that is not `last` (the press just kept or refused, until it
    /// is lifted or moved), for it to settle, and average it.
    async fn settled_press(
        &mut self,
        background: &RgbImage,
        ball_radius_px: f64,
        mut last: Option<ContactCircle>,
    ) -> Result<RgbImage, Stop> {
        let mut run: Vec<ContactCircle> = Vec::new();
        let mut said = "";
        let mut recent: std::collections::VecDeque<RgbImage> = Default::default();
        loop {
            // Each look is at the mean of the last frames: a single frame's noise hides a
            // shallow press that the averaged press shows.
            recent.push_back(self.frame().await?);
            if recent.len() > SETTLE_FRAMES {
                recent.pop_front();
            }
            let img = average(recent.make_contiguous())?;
            let found = detect(&img, background, ball_radius_px);
            self.show(&img, background, found.as_ref().ok().copied());
            let c = match found {
                Ok(c) => c,
                Err(why) => {
                    // Say once why a contact that is there is not taken.
                    if !matches!(why, Rejection::NoContact { .. }) && said != why.code() {
                        eprintln!("  waiting: {why}");
                        said = why.code();
                        let why = why.to_string();
                        self.view.update(|v| {
                            v.label = None;
                            v.rejection = Some(why);
                        });
                    }
                    last = None;
                    run.clear();
                    continue;
                }
            };
            said = "";
            if last.is_some_and(|l| same(&l, &c)) {
                continue;
            }
            last = None;
            if run.last().is_some_and(|p| !same(p, &c)) {
                run.clear();
            }
            run.push(c);
            if run.len() >= SETTLE_FRAMES {
                return Ok(average(&self.frames(AVERAGE_FRAMES).await?)?);
            }
        }
    }
}

/// A decision the page took: said on stderr, and kept to be answered once acted on.
fn page_decision(
    answer: gelgrip_web::calibrate::PageAnswer,
) -> (Decision, Option<gelgrip_web::calibrate::PageAnswer>) {
    eprintln!("  {} (from the dashboard)", answer.decision.as_str());
    (answer.decision, Some(answer))
}

fn same(a: &ContactCircle, b: &ContactCircle) -> bool {
    (a.center_x_px - b.center_x_px).hypot(a.center_y_px - b.center_y_px) <= SAME_CENTRE_PX
        && (a.contact_radius_px / b.contact_radius_px - 1.0).abs() <= SAME_RADIUS
}

/// The per-pixel mean of `frames` (all one size), rounded.
fn average(frames: &[RgbImage]) -> anyhow::Result<RgbImage> {
    let first = frames.first().context("no frames to average")?;
    let mut sum = vec![0u32; first.data.len()];
    for f in frames {
        anyhow::ensure!(
            f.data.len() == sum.len(),
            "frames of different sizes: {}x{} and {}x{}",
            first.width,
            first.height,
            f.width,
            f.height
        );
        sum.iter_mut()
            .zip(&f.data)
            .for_each(|(s, v)| *s += u32::from(*v));
    }
    let n = frames.len() as u32;
    Ok(RgbImage {
        width: first.width,
        height: first.height,
        data: sum.iter().map(|s| ((s + n / 2) / n) as u8).collect(),
    })
}
