//! Fuzz and fault suite: seeded mutations of the shipped configs (`configs/*.toml`) and data
//! (`data/*.csv`) run through the binary the way a user would, each under a timeout.
//!
//! Mutations: deleted keys, wrong types, extreme and non-finite numbers, swapped and renamed
//! sections, truncated files, empty files, random bytes; for data, wrong delimiters, NaN and
//! garbage cells, huge values, dropped columns, rows out of order, truncation.
//!
//! Every case must: not panic (no "panicked" in stderr, exit code neither 101 nor 134, not killed
//! by a signal); on failure, give a located message (the file and a line, column or key); leave
//! no output behind after a failure; and finish within the timeout (the process is killed and
//! the case fails). The run is bounded by construction, not by measuring it: every case gets
//! `--max-memory 512M`, and success cases are simulations of the shipped experiments, which take
//! a fraction of a second.
//!
//! `quick_fuzz_suite` runs a fixed seed in `cargo test`; `full_fuzz_suite` (ignored, run by
//! `just test`) runs more seeds. With `HTFID_FUZZ_LOG=FILE` every failure message is appended
//! to FILE, one line per case, for reading what a user would see.

use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A case running longer than this is a hang (the slowest success case takes about a second).
const TIMEOUT: Duration = Duration::from_secs(30);

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The config kinds, by the command that takes them.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    Experiment,
    Diagnose,
    Estimate,
}

/// A shipped config, shrunk so that a run that succeeds finishes fast.
struct Base {
    name: String,
    kind: Kind,
    text: String,
}

/// One generated case: files to write (relative to the case folder) and the command line.
struct Case {
    id: usize,
    what: String,
    config: String,
    data: Option<Vec<u8>>,
    command: &'static str,
}

fn bases() -> Vec<Base> {
    let mut out = Vec::new();
    let mut entries: Vec<_> = fs::read_dir(root().join("configs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    entries.sort();
    for path in entries {
        let name = path.file_stem().unwrap().to_string_lossy().into_owned();
        let text = fs::read_to_string(&path).unwrap();
        let table: toml::Table = text.parse().unwrap();
        let kind = if !table.contains_key("data") {
            Kind::Experiment
        } else if table.contains_key("period") {
            Kind::Estimate
        } else {
            Kind::Diagnose
        };
        // Data outside the repository (the Silverbox benchmark) may be absent on a fresh machine.
        if text.contains("../../shared") {
            continue;
        }
        out.push(Base { name, kind, text });
    }
    assert!(out.len() >= 8, "the shipped configs were found");
    out
}

/// The shipped data file, shortened to its first 60 s so that runs on it stay fast.
fn base_data() -> String {
    let text = fs::read_to_string(root().join("data/hopper-protocol.csv")).unwrap();
    let mut out = String::new();
    for line in text.lines() {
        if let Some((t, _)) = line.split_once(',') {
            if t.parse::<f64>().is_ok_and(|t| t > 60.0) {
                break;
            }
        }
        out.push_str(line);
        out.push('\n');
    }
    out
}

const EXTREMES: [&str; 14] = [
    "0",
    "-1",
    "1e300",
    "-1e300",
    "1e-300",
    "nan",
    "inf",
    "-inf",
    "9223372036854775807",
    "-9223372036854775808",
    "1e9",
    "1e-9",
    "0.5",
    "7",
];

const WRONG_TYPES: [&str; 6] = [
    "\"text\"",
    "true",
    "[1, 2]",
    "{ a = 1 }",
    "[\"x\", \"y\"]",
    "1979-05-27",
];

/// Every `(table path, key)` of a TOML document, depth first.
fn leaves(table: &toml::Table, prefix: &[String], out: &mut Vec<Vec<String>>) {
    for (k, v) in table {
        let mut path = prefix.to_vec();
        path.push(k.clone());
        if let toml::Value::Table(t) = v {
            leaves(t, &path, out);
        }
        out.push(path);
    }
}

fn get_parent<'a>(table: &'a mut toml::Table, path: &[String]) -> &'a mut toml::Table {
    let mut t = table;
    for k in &path[..path.len() - 1] {
        t = t.get_mut(k).and_then(|v| v.as_table_mut()).unwrap();
    }
    t
}

/// A value parsed from TOML text (`nan`, `1979-05-27`, ...), as the value of a key.
fn toml_value(text: &str) -> toml::Value {
    let doc: toml::Table = format!("v = {text}").parse().unwrap();
    doc["v"].clone()
}

fn mutate_config(rng: &mut ChaCha8Rng, text: &str) -> (String, String) {
    let mut table: toml::Table = text.parse().unwrap();
    let mut paths = Vec::new();
    leaves(&table, &[], &mut paths);
    let path = paths.choose(rng).unwrap().clone();
    let dotted = path.join(".");
    let kind = rng.gen_range(0..10);
    match kind {
        0 => {
            get_parent(&mut table, &path).remove(path.last().unwrap());
            (format!("delete {dotted}"), toml::to_string(&table).unwrap())
        }
        1 | 2 => {
            let v = *WRONG_TYPES.choose(rng).unwrap();
            get_parent(&mut table, &path).insert(path.last().unwrap().clone(), toml_value(v));
            (format!("{dotted} = {v}"), toml::to_string(&table).unwrap())
        }
        3..=5 => {
            // Numbers only where a number was, so the mutation reaches the range checks.
            let numeric: Vec<&Vec<String>> = paths
                .iter()
                .filter(|p| {
                    let mut t = &table;
                    for k in &p[..p.len() - 1] {
                        t = t[k].as_table().unwrap();
                    }
                    matches!(
                        t[p.last().unwrap()],
                        toml::Value::Integer(_) | toml::Value::Float(_)
                    )
                })
                .collect();
            let path = numeric.choose(rng).map_or(path.clone(), |p| (*p).clone());
            let v = *EXTREMES.choose(rng).unwrap();
            get_parent(&mut table, &path).insert(path.last().unwrap().clone(), toml_value(v));
            (
                format!("{} = {v}", path.join(".")),
                toml::to_string(&table).unwrap(),
            )
        }
        6 => {
            // Swap the contents of two top-level tables.
            let tables: Vec<String> = table
                .iter()
                .filter(|(_, v)| v.is_table())
                .map(|(k, _)| k.clone())
                .collect();
            if tables.len() >= 2 {
                let pick: Vec<&String> = tables.choose_multiple(rng, 2).collect();
                let (a, b) = (pick[0].clone(), pick[1].clone());
                let va = table.remove(&a).unwrap();
                let vb = table.remove(&b).unwrap();
                table.insert(a.clone(), vb);
                table.insert(b.clone(), va);
                (
                    format!("swap [{a}] and [{b}]"),
                    toml::to_string(&table).unwrap(),
                )
            } else {
                (format!("delete {dotted}"), {
                    get_parent(&mut table, &path).remove(path.last().unwrap());
                    toml::to_string(&table).unwrap()
                })
            }
        }
        7 => {
            // Truncate the text at a random character.
            let chars: Vec<char> = text.chars().collect();
            let at = rng.gen_range(0..chars.len());
            (
                format!("truncated at char {at}"),
                chars[..at].iter().collect(),
            )
        }
        8 => {
            // A key renamed to a near miss (a typo).
            let parent = get_parent(&mut table, &path);
            let v = parent.remove(path.last().unwrap()).unwrap();
            parent.insert(format!("{}x", path.last().unwrap()), v);
            (
                format!("rename {dotted} to {dotted}x"),
                toml::to_string(&table).unwrap(),
            )
        }
        _ => {
            // A huge value where a number was expected, written as text the parser must reject
            // or range-check.
            let v = ["1e400", "0x7fffffffffffffff", "1_000_000_000_000", "-0.0"]
                .choose(rng)
                .unwrap()
                .to_string();
            let line = text
                .lines()
                .filter(|l| l.contains(" = ") && !l.trim_start().starts_with('#'))
                .collect::<Vec<_>>()
                .choose(rng)
                .map(|l| l.to_string())
                .unwrap_or_default();
            let key = line.split(" = ").next().unwrap_or("").to_string();
            (
                format!("{} = {v} (text)", key.trim()),
                text.replacen(&line, &format!("{key} = {v}"), 1),
            )
        }
    }
}

fn mutate_data(rng: &mut ChaCha8Rng, text: &str) -> (String, Vec<u8>) {
    let lines: Vec<&str> = text.lines().collect();
    let header = lines.iter().position(|l| l.starts_with("t,")).unwrap();
    let body = header + 1..lines.len();
    let join = |ls: &[String]| ls.join("\n").into_bytes();
    let mut owned: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
    match rng.gen_range(0..12) {
        0 => {
            let at = rng.gen_range(0..text.len());
            ("data truncated".into(), text.as_bytes()[..at].to_vec())
        }
        1 => {
            let d = *[";", "\t", " ", "|"].choose(rng).unwrap();
            (
                format!("delimiter {d:?}"),
                text.replace(',', d).into_bytes(),
            )
        }
        2 | 3 => {
            let i = rng.gen_range(body.clone());
            let cell = *["NaN", "nan", "", "inf", "-inf", "1e400", "abc", "1,2"]
                .choose(rng)
                .unwrap();
            let mut cells: Vec<String> = owned[i].split(',').map(str::to_string).collect();
            let c = rng.gen_range(0..cells.len());
            cells[c] = cell.to_string();
            owned[i] = cells.join(",");
            (
                format!("cell {c} of line {} = {cell:?}", i + 1),
                join(&owned),
            )
        }
        4 => ("empty data".into(), Vec::new()),
        5 => ("header only".into(), join(&owned[..=header])),
        6 => {
            for l in &mut owned[body.clone()] {
                let mut cells: Vec<String> = l.split(',').map(str::to_string).collect();
                let last = cells.len() - 1;
                if let Ok(v) = cells[last].parse::<f64>() {
                    cells[last] = format!("{:e}", v * 1e300);
                }
                *l = cells.join(",");
            }
            ("huge outputs".into(), join(&owned))
        }
        7 => {
            let bytes: Vec<u8> = (0..rng.gen_range(1..4096)).map(|_| rng.gen()).collect();
            ("random bytes".into(), bytes)
        }
        8 => {
            // Drop a column everywhere.
            let c = rng.gen_range(0..3);
            for l in &mut owned[header..] {
                let mut cells: Vec<&str> = l.split(',').collect();
                if c < cells.len() {
                    cells.remove(c);
                }
                *l = cells.join(",");
            }
            (format!("column {c} dropped"), join(&owned))
        }
        9 => {
            let i = rng.gen_range(body.start..body.end - 1);
            owned.swap(i, i + 1);
            (
                format!("lines {} and {} swapped", i + 1, i + 2),
                join(&owned),
            )
        }
        10 => {
            let i = rng.gen_range(body.clone());
            owned.insert(i, owned[i].clone());
            (format!("line {} repeated", i + 1), join(&owned))
        }
        _ => {
            // A short record: a few lines only.
            let keep = header + 1 + rng.gen_range(0..80);
            (
                format!("only {} rows", keep - header - 1),
                join(&owned[..keep.min(owned.len())]),
            )
        }
    }
}

fn command(kind: Kind) -> &'static str {
    match kind {
        Kind::Experiment => "simulate",
        Kind::Diagnose => "diagnose",
        Kind::Estimate => "estimate",
    }
}

/// `count` cases from `seed`: about two thirds config mutations, the rest data mutations of the
/// configs that read data.
fn generate(seed: u64, count: usize) -> Vec<Case> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let bases = bases();
    let data = base_data();
    let readers: Vec<&Base> = bases
        .iter()
        .filter(|b| b.kind != Kind::Experiment)
        .collect();
    let mut cases = Vec::new();
    for id in 0..count {
        let case = match rng.gen_range(0..20) {
            // Whole-file faults.
            0 => {
                let b = bases.choose(&mut rng).unwrap();
                Case {
                    id,
                    what: format!("{}: empty config", b.name),
                    config: String::new(),
                    data: None,
                    command: command(b.kind),
                }
            }
            1 => {
                let b = bases.choose(&mut rng).unwrap();
                let bytes: Vec<u8> = (0..rng.gen_range(1..512)).map(|_| rng.gen()).collect();
                Case {
                    id,
                    what: format!("{}: random bytes", b.name),
                    config: String::from_utf8_lossy(&bytes).into_owned(),
                    data: None,
                    command: command(b.kind),
                }
            }
            2..=13 => {
                let b = bases.choose(&mut rng).unwrap();
                let (what, config) = mutate_config(&mut rng, &b.text);
                Case {
                    id,
                    what: format!("{}: {what}", b.name),
                    config,
                    data: None,
                    command: command(b.kind),
                }
            }
            _ => {
                let b = readers.choose(&mut rng).unwrap();
                let (what, bytes) = mutate_data(&mut rng, &data);
                Case {
                    id,
                    what: format!("{}: {what}", b.name),
                    config: b.text.replace("hopper-protocol.csv", "mutated.csv"),
                    data: Some(bytes),
                    command: command(b.kind),
                }
            }
        };
        cases.push(case);
    }
    cases
}

/// Whether `err` names a place: a line number after a file name, a line or column, a dotted
/// key (`simulation.sample_rate`), a backticked name (TOML's "missing field `model`") or a
/// `[section]`.
fn names_a_place(err: &str) -> bool {
    if err.contains("line ") || err.contains("column ") {
        return true;
    }
    if err.contains(".toml:") || err.contains(".csv:") {
        let after = |ext: &str| {
            err.match_indices(ext)
                .any(|(i, _)| err[i + ext.len()..].starts_with(|c: char| c.is_ascii_digit()))
        };
        if after(".toml:") || after(".csv:") {
            return true;
        }
    }
    if err.contains('`') || (err.contains('[') && err.contains(']')) {
        return true;
    }
    err.split(|c: char| !(c.is_ascii_alphanumeric() || c == '_' || c == '.'))
        .any(|tok| {
            let Some((a, b)) = tok.split_once('.') else {
                return false;
            };
            let word = |s: &str| s.starts_with(|c: char| c.is_ascii_lowercase());
            word(a) && word(b) && !["toml", "csv", "md", "json", "svg", "png"].contains(&b)
        })
}

/// Runs one case in its own folder; returns a description of what went wrong, if anything.
fn run_case(dir: &Path, case: &Case) -> Option<String> {
    let folder = dir.join(format!("case-{}", case.id));
    let configs = folder.join("configs");
    fs::create_dir_all(&configs).unwrap();
    fs::create_dir_all(folder.join("data")).unwrap();
    // Model files are named relative to the config, as in the repository.
    let models = folder.join("models");
    fs::create_dir_all(&models).unwrap();
    for e in fs::read_dir(root().join("models")).unwrap() {
        let p = e.unwrap().path();
        if p.is_file() {
            fs::copy(&p, models.join(p.file_name().unwrap())).unwrap();
        }
    }
    fs::write(folder.join("data/hopper-protocol.csv"), base_data()).unwrap();
    if let Some(bytes) = &case.data {
        fs::write(folder.join("data/mutated.csv"), bytes).unwrap();
    }
    let config = configs.join("case.toml");
    fs::write(&config, &case.config).unwrap();
    let out = folder.join("out");
    let started = Instant::now();
    let mut child = Command::new(env!("CARGO_BIN_EXE_htfid"))
        .args([
            case.command,
            config.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--max-memory",
            "512M",
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the htfid binary runs");
    // Drain stderr on a thread so a chatty child cannot block on a full pipe.
    let mut pipe = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = std::io::Read::read_to_string(&mut pipe, &mut s);
        s
    });
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break Some(status);
        }
        if started.elapsed() > TIMEOUT {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    let err = reader.join().unwrap_or_default();
    let describe = |problem: &str| {
        Some(format!(
            "case {} ({}): htfid {} : {problem}\n    stderr: {}",
            case.id,
            case.what,
            case.command,
            err.trim().replace('\n', "\n            ")
        ))
    };
    let Some(status) = status else {
        return describe(&format!(
            "killed after {TIMEOUT:?} (a hang or a long silent run)"
        ));
    };
    if err.contains("panicked") {
        return describe("panicked");
    }
    match status.code() {
        None => return describe("killed by a signal"),
        Some(101) => return describe("exit code 101 (panic)"),
        Some(134) => return describe("exit code 134 (abort, out of memory)"),
        Some(0) => return None,
        Some(_) => {}
    }
    // Only the error itself counts, not the progress lines before it.
    let message = err.find("error:").map_or("", |i| &err[i..]);
    if let Ok(log) = std::env::var("HTFID_FUZZ_LOG") {
        // A record of every message, for reading what users would see.
        if let Ok(mut f) = fs::OpenOptions::new().create(true).append(true).open(log) {
            let _ = std::io::Write::write_all(
                &mut f,
                format!("{} | {}\n", case.what, message.trim().replace('\n', " / ")).as_bytes(),
            );
        }
    }
    let names_file = message.contains("case.toml") || message.contains("mutated.csv");
    if !names_file || !names_a_place(message) {
        return describe("the message names no file and key, line or column");
    }
    let leftovers: Vec<_> = fs::read_dir(&out)
        .map(|d| d.filter_map(|e| e.ok()).map(|e| e.path()).collect())
        .unwrap_or_default();
    if !leftovers.is_empty() {
        return describe(&format!("a failed run left {leftovers:?}"));
    }
    let _ = fs::remove_dir_all(&folder);
    None
}

/// Runs the cases on two threads and fails with every problem found.
fn run_suite(seed: u64, count: usize) {
    let cases = generate(seed, count);
    assert!(cases.len() >= count);
    let tmp = tempfile::tempdir().unwrap();
    let next = Mutex::new(0usize);
    let problems = Mutex::new(Vec::new());
    let outcomes = Mutex::new([0usize; 2]);
    std::thread::scope(|s| {
        for _ in 0..2 {
            s.spawn(|| loop {
                let i = {
                    let mut n = next.lock().unwrap();
                    let i = *n;
                    *n += 1;
                    i
                };
                let Some(case) = cases.get(i) else { break };
                let problem = run_case(tmp.path(), case);
                let mut o = outcomes.lock().unwrap();
                o[usize::from(problem.is_some())] += 1;
                if let Some(p) = problem {
                    problems.lock().unwrap().push(p);
                }
            });
        }
    });
    let problems = problems.into_inner().unwrap();
    let mut report = String::new();
    for p in &problems {
        let _ = writeln!(report, "{p}");
    }
    assert!(
        problems.is_empty(),
        "{} of {} fuzz cases (seed {seed}) failed:\n{report}",
        problems.len(),
        cases.len()
    );
}

#[test]
fn quick_fuzz_suite() {
    run_suite(20261124, 220);
}

#[test]
#[ignore = "about four times the quick suite; run by `just test`"]
fn full_fuzz_suite() {
    for seed in 1..=4 {
        run_suite(seed, 220);
    }
}

/// The generator is deterministic and covers every kind of mutation, so a failing case can be
/// reproduced from its seed and number.
#[test]
fn the_generator_is_seeded_and_covers_its_mutations() {
    let a = generate(7, 220);
    let b = generate(7, 220);
    assert!(a
        .iter()
        .zip(&b)
        .all(|(x, y)| x.config == y.config && x.data == y.data && x.what == y.what));
    let whats: Vec<&str> = a.iter().map(|c| c.what.as_str()).collect();
    for needle in [
        "empty config",
        "random bytes",
        "delete ",
        "swap [",
        "truncated at char",
        "rename ",
        "delimiter",
        "cell ",
        "empty data",
        " = nan",
    ] {
        assert!(
            whats.iter().any(|w| w.contains(needle)),
            "no case of kind {needle:?}"
        );
    }
    for command in ["simulate", "diagnose", "estimate"] {
        assert!(a.iter().any(|c| c.command == command), "no {command} case");
    }
}
