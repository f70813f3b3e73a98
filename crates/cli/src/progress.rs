//! Progress on standard error, so that standard output carries only the results.
//!
//! Three modes, chosen once by [`init`]: `--quiet` prints nothing; on a terminal every stage
//! shows a spinner with its elapsed time (a bar with an ETA where the work is counted) and
//! leaves one line with its duration; otherwise (a log, a pipe) plain lines, one per stage.

use std::io::IsTerminal;
use std::sync::{Mutex, OnceLock};
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressStyle};

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    Quiet,
    Plain,
    Terminal,
}

static MODE: OnceLock<Mode> = OnceLock::new();
/// The bar or spinner on screen, so that lines printed meanwhile go above it.
static ACTIVE: Mutex<Option<ProgressBar>> = Mutex::new(None);

/// Chooses the mode for the process: quiet, or by whether stderr is a terminal.
pub fn init(quiet: bool) {
    let mode = if quiet {
        Mode::Quiet
    } else if std::io::stderr().is_terminal() {
        Mode::Terminal
    } else {
        Mode::Plain
    };
    let _ = MODE.set(mode);
}

fn mode() -> Mode {
    *MODE.get().unwrap_or(&Mode::Plain)
}

fn active() -> std::sync::MutexGuard<'static, Option<ProgressBar>> {
    ACTIVE.lock().unwrap_or_else(|e| e.into_inner())
}

/// A line of progress (`[htfid] msg`), unless quiet.
pub fn line(msg: &str) {
    match mode() {
        Mode::Quiet => {}
        Mode::Plain => eprintln!("[htfid] {msg}"),
        Mode::Terminal => match active().as_ref() {
            Some(bar) => bar.println(format!("[htfid] {msg}")),
            None => eprintln!("[htfid] {msg}"),
        },
    }
}

/// Clears the bar on screen (before the process exits on a signal or an error).
pub fn clear() {
    if let Some(bar) = active().take() {
        bar.finish_and_clear();
    }
}

fn show(bar: ProgressBar) -> ProgressBar {
    bar.enable_steady_tick(Duration::from_millis(120));
    *active() = Some(bar.clone());
    bar
}

fn hide(bar: &ProgressBar) {
    bar.finish_and_clear();
    active().take();
}

/// Times stages and reports them on stderr.
#[derive(Debug, Default)]
pub struct Stages {
    timings: Vec<(String, f64)>,
    /// Stages of a worker thread: timed, shown when absorbed by the main thread's stages.
    silent: bool,
    /// When the main thread's stages began (`wall` in the JSON).
    started: Option<Instant>,
}

impl Stages {
    pub fn new() -> Self {
        Stages {
            started: Some(Instant::now()),
            ..Stages::default()
        }
    }

    /// Stages run on a worker thread, beside others: timed but not shown until
    /// [`Stages::absorb`], so that lines of parallel stages never interleave.
    pub fn silent() -> Self {
        Stages {
            silent: true,
            ..Stages::default()
        }
    }

    /// Takes the timings of stages that ran on a worker thread, showing each as run in
    /// parallel.
    pub fn absorb(&mut self, other: Stages) {
        for (name, ms) in other.timings {
            // A worker's stages absorbed by another worker are shown with that worker's.
            if !self.silent && mode() != Mode::Quiet {
                eprintln!("[htfid] {name} ... {} (in parallel)", duration(ms));
            }
            self.timings.push((name, ms));
        }
    }

    /// Runs `f` as the stage `name`, showing it while it runs and its duration after.
    pub fn run<T>(&mut self, name: &str, f: impl FnOnce() -> T) -> T {
        if self.silent {
            let start = Instant::now();
            let out = f();
            self.timings
                .push((name.to_string(), start.elapsed().as_secs_f64() * 1e3));
            return out;
        }
        let spinner = match mode() {
            Mode::Quiet => None,
            Mode::Plain => {
                eprint!("[htfid] {name} ... ");
                None
            }
            Mode::Terminal => Some(show(
                ProgressBar::new_spinner()
                    .with_style(
                        ProgressStyle::with_template("{spinner} {msg} {elapsed}")
                            .expect("a valid template"),
                    )
                    .with_message(name.to_string()),
            )),
        };
        let start = Instant::now();
        let out = f();
        let ms = start.elapsed().as_secs_f64() * 1e3;
        if let Some(s) = &spinner {
            hide(s);
            eprintln!("[htfid] {name} ... {}", duration(ms));
        } else if mode() == Mode::Plain {
            eprintln!("{}", duration(ms));
        }
        self.timings.push((name.to_string(), ms));
        out
    }

    /// `{"stage": ms, ...}` in the order run; `total` is their sum (stages run in parallel
    /// overlap, so it can exceed the wall time).
    pub fn to_json(&self) -> serde_json::Value {
        let mut map = serde_json::Map::new();
        let mut total = 0.0;
        for (name, ms) in &self.timings {
            map.insert(name.clone(), serde_json::json!(round3(*ms)));
            total += ms;
        }
        map.insert("total".into(), serde_json::json!(round3(total)));
        if let Some(started) = self.started {
            map.insert(
                "wall".into(),
                serde_json::json!(round3(started.elapsed().as_secs_f64() * 1e3)),
            );
        }
        serde_json::Value::Object(map)
    }
}

/// `12.3 ms` or `4.56 s`.
fn duration(ms: f64) -> String {
    if ms < 1000.0 {
        format!("{ms:.1} ms")
    } else {
        format!("{:.2} s", ms / 1e3)
    }
}

fn round3(x: f64) -> f64 {
    (x * 1e3).round() / 1e3
}
