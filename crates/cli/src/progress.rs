//! Progress lines on standard error: one line per stage with its duration, so long work is
//! visible on a terminal and quiet in logs.

use std::time::Instant;

/// Times stages and reports them on stderr.
#[derive(Debug)]
pub struct Stages {
    quiet: bool,
    timings: Vec<(String, f64)>,
}

impl Stages {
    pub fn new(quiet: bool) -> Self {
        Stages {
            quiet,
            timings: Vec::new(),
        }
    }

    /// Runs `f` as the stage `name`, printing its start and duration.
    pub fn run<T>(&mut self, name: &str, f: impl FnOnce() -> T) -> T {
        if !self.quiet {
            eprint!("[htfid] {name} ... ");
        }
        let start = Instant::now();
        let out = f();
        let ms = start.elapsed().as_secs_f64() * 1e3;
        if !self.quiet {
            eprintln!("{ms:.1} ms");
        }
        self.timings.push((name.to_string(), ms));
        out
    }

    /// `{"stage": ms, ...}` in the order run.
    pub fn to_json(&self) -> serde_json::Value {
        let mut map = serde_json::Map::new();
        let mut total = 0.0;
        for (name, ms) in &self.timings {
            map.insert(name.clone(), serde_json::json!(round3(*ms)));
            total += ms;
        }
        map.insert("total".into(), serde_json::json!(round3(total)));
        serde_json::Value::Object(map)
    }
}

fn round3(x: f64) -> f64 {
    (x * 1e3).round() / 1e3
}
