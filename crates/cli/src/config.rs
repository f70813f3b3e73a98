//! Experiment configs: raw TOML options (serde, unknown keys rejected) resolved into checked
//! settings. Every range error names the file, the line, the key and what was expected.

use std::fmt;
use std::ops::Range;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use toml::Spanned;

/// A config problem located in a file.
#[derive(Debug)]
pub struct ConfigError {
    pub path: PathBuf,
    pub line: Option<usize>,
    /// 1-based column of the value (or key) on `line`, in characters.
    pub column: Option<usize>,
    pub key: String,
    pub message: String,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.path.display())?;
        if let Some(line) = self.line {
            write!(f, ":{line}")?;
            if let Some(column) = self.column {
                write!(f, ":{column}")?;
            }
        }
        // Parse errors carry no key of their own: the TOML message names it.
        if self.key != "toml" {
            write!(f, ": {}", self.key)?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for ConfigError {}

/// The source text of a config, for turning spans into line numbers.
#[derive(Debug)]
pub struct Source {
    pub path: PathBuf,
    pub text: String,
}

impl Source {
    pub fn line_of(&self, span: &Range<usize>) -> usize {
        let end = span.start.min(self.text.len());
        self.text[..end].bytes().filter(|&b| b == b'\n').count() + 1
    }

    /// The 1-based column (in characters) where `span` starts, as editors count.
    pub fn column_of(&self, span: &Range<usize>) -> usize {
        let mut end = span.start.min(self.text.len());
        while !self.text.is_char_boundary(end) {
            end -= 1;
        }
        let start = self.text[..end].rfind('\n').map_or(0, |i| i + 1);
        self.text[start..end].chars().count() + 1
    }

    /// Where `key = ...` is written inside the table that starts at `table_start` (a
    /// `toml::Table` value keeps no spans of its own entries).
    pub fn key_in_table(&self, table_start: usize, key: &str) -> Option<Range<usize>> {
        let mut offset = table_start.min(self.text.len());
        // From the line after the table's header, until the next header.
        if let Some(nl) = self.text[offset..].find('\n') {
            offset += nl + 1;
        }
        for line in self.text[offset..].split_inclusive('\n') {
            let trimmed = line.trim_start();
            if trimmed.starts_with('[') {
                return None;
            }
            if let Some(rest) = trimmed.strip_prefix(key) {
                if rest.trim_start().starts_with('=') {
                    let at = offset + (line.len() - trimmed.len());
                    return Some(at..at + key.len());
                }
            }
            offset += line.len();
        }
        None
    }

    /// Where `key = ...` is written in the table `[table]` (a top-level table written with its
    /// own header), for an error found after the config was read.
    pub fn key_location(&self, table: &str, key: &str) -> Option<Range<usize>> {
        let header = format!("[{table}]");
        let mut offset = 0;
        for line in self.text.split_inclusive('\n') {
            let trimmed = line.trim();
            if trimmed == header
                || trimmed
                    .strip_prefix(header.as_str())
                    .is_some_and(|rest| rest.trim_start().starts_with('#'))
            {
                return self.key_in_table(offset, key);
            }
            offset += line.len();
        }
        None
    }

    pub fn error(
        &self,
        span: Option<&Range<usize>>,
        key: &str,
        message: impl Into<String>,
    ) -> ConfigError {
        ConfigError {
            path: self.path.clone(),
            line: span.map(|s| self.line_of(s)),
            column: span.map(|s| self.column_of(s)),
            key: key.to_string(),
            message: message.into(),
        }
    }

    /// The run's name, which names its output folder: `name` as configured, else the config
    /// file's stem, else `fallback`; a plain file name either way.
    pub fn run_name(
        &self,
        name: Option<&Spanned<String>>,
        fallback: &str,
    ) -> Result<String, ConfigError> {
        let s = match name {
            Some(n) => n.get_ref().trim().to_string(),
            None => self
                .path
                .file_stem()
                .map_or_else(|| fallback.into(), |s| s.to_string_lossy().into_owned()),
        };
        if s.is_empty() || s.contains(['/', '\\']) || s.starts_with('.') {
            return Err(self.error(
                name.map(Spanned::span).as_ref(),
                "name",
                format!(
                    "must be a plain file name (no slashes, not empty, not starting with '.') \
                     (got \"{s}\")"
                ),
            ));
        }
        Ok(s)
    }

    /// A number that must satisfy `ok`; `expected` is what the message says.
    pub fn number(
        &self,
        value: &Spanned<f64>,
        key: &str,
        expected: &str,
        ok: impl Fn(f64) -> bool,
    ) -> Result<f64, ConfigError> {
        let v = *value.get_ref();
        if v.is_finite() && ok(v) {
            Ok(v)
        } else {
            Err(self.error(
                Some(&value.span()),
                key,
                format!("must be {expected} (got {})", show(v)),
            ))
        }
    }

    /// A band of the spectrum as fractions of the Nyquist frequency: two numbers,
    /// `0 < lo < hi <= 1`.
    pub fn band(&self, value: &Spanned<Vec<f64>>, key: &str) -> Result<(f64, f64), ConfigError> {
        match value.get_ref().as_slice() {
            &[lo, hi] if lo.is_finite() && hi.is_finite() && lo > 0.0 && lo < hi && hi <= 1.0 => {
                Ok((lo, hi))
            }
            v => Err(self.error(
                Some(&value.span()),
                key,
                format!(
                    "must be two fractions of the Nyquist frequency [lo, hi] with 0 < lo < hi \
                     <= 1 (got [{}])",
                    v.iter().map(|&x| show(x)).collect::<Vec<_>>().join(", ")
                ),
            )),
        }
    }

    /// Rows `[start, end)` of a record, 0-based sample indices with `0 <= start < end`; that
    /// `end` lies inside the record is checked when it is read.
    pub fn rows(&self, value: &Spanned<Vec<i64>>, key: &str) -> Result<Range<usize>, ConfigError> {
        match value.get_ref().as_slice() {
            &[a, b] if a >= 0 && b > a => Ok(a as usize..b as usize),
            v => Err(self.error(
                Some(&value.span()),
                key,
                format!(
                    "must be [start, end): two sample indices with 0 <= start < end (got [{}])",
                    v.iter().map(i64::to_string).collect::<Vec<_>>().join(", ")
                ),
            )),
        }
    }

    pub fn positive(&self, value: &Spanned<f64>, key: &str) -> Result<f64, ConfigError> {
        self.number(value, key, "> 0", |v| v > 0.0)
    }

    pub fn non_negative(&self, value: &Spanned<f64>, key: &str) -> Result<f64, ConfigError> {
        self.number(value, key, ">= 0", |v| v >= 0.0)
    }

    pub fn finite(&self, value: &Spanned<f64>, key: &str) -> Result<f64, ConfigError> {
        self.number(value, key, "a finite number", |_| true)
    }

    /// An optional number with a default.
    pub fn opt_number(
        &self,
        value: &Option<Spanned<f64>>,
        default: f64,
        key: &str,
        expected: &str,
        ok: impl Fn(f64) -> bool,
    ) -> Result<f64, ConfigError> {
        match value {
            Some(v) => self.number(v, key, expected, ok),
            None => Ok(default),
        }
    }

    /// A string that must be one of `choices`.
    pub fn choice<'a>(
        &self,
        value: &'a Spanned<String>,
        key: &str,
        choices: &[&str],
    ) -> Result<&'a str, ConfigError> {
        let v = value.get_ref().as_str();
        if choices.contains(&v) {
            Ok(v)
        } else {
            Err(self.error(
                Some(&value.span()),
                key,
                format!("must be one of {} (got \"{v}\")", quote_list(choices)),
            ))
        }
    }

    /// Rejects a key that has no meaning for the chosen variant.
    pub fn forbid<T>(
        &self,
        value: &Option<Spanned<T>>,
        key: &str,
        why: &str,
    ) -> Result<(), ConfigError> {
        match value {
            Some(v) => Err(self.error(
                Some(&v.span()),
                key,
                format!("is not used {why}; remove it"),
            )),
            None => Ok(()),
        }
    }

    pub fn require<'a, T>(
        &self,
        value: &'a Option<Spanned<T>>,
        key: &str,
        why: &str,
    ) -> Result<&'a Spanned<T>, ConfigError> {
        value
            .as_ref()
            .ok_or_else(|| self.error(None, key, format!("is required {why}")))
    }
}

/// A number as a config's reader would write it: plain for everyday magnitudes, in exponent
/// form beyond them (`1e308`, not 309 digits).
pub fn show(v: f64) -> String {
    if v == 0.0 || !v.is_finite() || (1e-4..1e6).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

pub fn quote_list(choices: &[&str]) -> String {
    choices
        .iter()
        .map(|c| format!("\"{c}\""))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Reads and parses a config file into raw options.
pub fn load<T: for<'de> Deserialize<'de>>(
    path: &Path,
    kind: Kind,
) -> Result<(T, Source), ConfigError> {
    let text = std::fs::read_to_string(path).map_err(|e| ConfigError {
        path: path.to_path_buf(),
        line: None,
        column: None,
        key: "file".into(),
        message: format!("cannot read: {e}"),
    })?;
    let source = Source {
        path: path.to_path_buf(),
        text,
    };
    check_kind(&source, kind)?;
    // serde_path_to_error keeps the key path that toml's own messages lack
    // ("invalid type: string \"nine\", expected i64" names no key).
    let raw: T =
        serde_path_to_error::deserialize(toml::Deserializer::new(&source.text)).map_err(|e| {
            let key = key_path(e.path());
            let inner = e.into_inner();
            ConfigError {
                path: path.to_path_buf(),
                line: inner.span().map(|s| source.line_of(&s)),
                column: inner.span().map(|s| source.column_of(&s)),
                key: if key.is_empty() { "toml".into() } else { key },
                message: plain_types(inner.message().trim()),
            }
        })?;
    Ok((raw, source))
}

/// The dotted key of a path, without the segments serde uses inside `Spanned` values.
fn key_path(path: &serde_path_to_error::Path) -> String {
    use serde_path_to_error::Segment;
    let mut key = String::new();
    for segment in path.iter() {
        let part = match segment {
            Segment::Map { key } | Segment::Enum { variant: key } => key.clone(),
            Segment::Seq { index } => format!("[{index}]"),
            Segment::Unknown => continue,
        };
        if part.starts_with("$__") {
            continue;
        }
        if !key.is_empty() && !part.starts_with('[') {
            key.push('.');
        }
        key.push_str(&part);
    }
    key
}

/// Rust type names in serde's messages, said the way a config's reader knows them.
fn plain_types(message: &str) -> String {
    let mut m = message.to_owned();
    for (rust, plain) in [
        ("expected i64", "expected an integer"),
        ("expected i32", "expected an integer"),
        ("expected u64", "expected an integer >= 0"),
        ("expected u32", "expected an integer >= 0"),
        ("expected usize", "expected an integer >= 0"),
        ("expected f64", "expected a number"),
        ("expected f32", "expected a number"),
        (
            "expected an array of length 2",
            "expected a list of 2 items [start, end)",
        ),
        ("expected a sequence", "expected a list"),
    ] {
        m = m.replace(rust, plain);
    }
    // "expected struct RawForcing": the reader wrote a value where a table belongs.
    if let Some(at) = m.find("expected struct ") {
        let name_end = m[at + 16..]
            .find(|c: char| !c.is_alphanumeric() && c != '_')
            .map_or(m.len(), |i| at + 16 + i);
        m.replace_range(at..name_end, "expected a table");
    }
    m
}

/// The kinds of config: experiments (`simulate`, `theory`, `run`), diagnoses, and
/// model-free estimates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Experiment,
    Diagnosis,
    Estimate,
}

/// A clear message when a config of the other kind is given to a command.
fn check_kind(source: &Source, kind: Kind) -> Result<(), ConfigError> {
    // An unparsable file is reported by the typed parse that follows, with its line.
    let Ok(table) = source.text.parse::<toml::Table>() else {
        return Ok(());
    };
    let has_data = table.contains_key("data");
    let experiment_only = [
        "simulation",
        "excitation",
        "estimation",
        "theory",
        "noise",
        "effects",
    ]
    .iter()
    .find(|k| table.contains_key(**k));
    let is_estimate = has_data && table.contains_key("period") && !table.contains_key("model");
    let message = match (kind, has_data, experiment_only) {
        (Kind::Experiment | Kind::Diagnosis, true, _) if is_estimate => {
            "this is an estimate config (it has [data] and [period], no [model]); run it with \
             `htfid estimate`"
                .to_string()
        }
        (Kind::Estimate, _, _) if !is_estimate => {
            "`htfid estimate` needs a config with [data] and [period] and no [model] \
             (see configs/estimate-hopper.toml)"
                .to_string()
        }
        (Kind::Estimate, _, _) => return Ok(()),
        (Kind::Experiment, true, _) => {
            "this is a diagnosis config (it has [data]); run it with `htfid diagnose`".to_string()
        }
        (Kind::Diagnosis, false, Some(k)) => format!(
            "this is an experiment config (it has [{k}]); `htfid diagnose` needs a diagnosis \
             config with a [data] table (see configs/diagnose-hopper.toml)"
        ),
        (Kind::Diagnosis, true, _) => return check_model_file(source, &table),
        _ => return Ok(()),
    };
    Err(ConfigError {
        path: source.path.clone(),
        line: None,
        column: None,
        key: "config".into(),
        message,
    })
}

/// A diagnosis reads its model from a model file: a `[model]` of inline keys (the form
/// `simulate`, `theory` and `run` read for the built-in hopper) is refused with the way to
/// write it, at the line of `[model]`.
fn check_model_file(source: &Source, table: &toml::Table) -> Result<(), ConfigError> {
    let Some(model) = table.get("model").and_then(toml::Value::as_table) else {
        return Ok(());
    };
    if model.contains_key("file") {
        return Ok(());
    }
    let line = source
        .text
        .lines()
        .position(|l| l.trim_start().starts_with("[model]"))
        .map(|i| i + 1);
    let inline: Vec<&str> = model.keys().map(String::as_str).collect();
    Err(ConfigError {
        path: source.path.clone(),
        line,
        column: line.map(|_| 1),
        key: "model.file".into(),
        message: format!(
            "is missing (the inline keys here: {}): `htfid diagnose` reads its model from a \
             file in the model language (docs/models.md), as `file = \"../models/hopper.toml\"` \
             for the paper's hopper or `file = \"../models/spring-mass-damper.toml\"` for a \
             spring-mass-damper with an offset on its input; the parameters' values go in \
             [model.parameters] and `free` stays in [model] (docs/config.md, \"Diagnosis \
             configs\", shows each old key in the new form)",
            inline.join(", ")
        ),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Deserialize)]
    struct Named {
        name: Option<Spanned<String>>,
    }

    fn named(text: &str, path: &str) -> (Source, Option<Spanned<String>>) {
        let raw: Named = toml::from_str(text).unwrap();
        let src = Source {
            path: PathBuf::from(path),
            text: text.to_string(),
        };
        (src, raw.name)
    }

    /// Every config kind names its output folder through `run_name`: a configured name is
    /// trimmed, a missing one is the file's stem, and anything but a plain file name is
    /// refused at its line and column.
    #[test]
    fn a_run_name_is_a_plain_file_name() {
        let (src, name) = named("name = \"  swept \"\n", "dir/a.toml");
        assert_eq!(src.run_name(name.as_ref(), "x").unwrap(), "swept");
        let (src, name) = named("\n", "dir/a.toml");
        assert_eq!(src.run_name(name.as_ref(), "x").unwrap(), "a");
        for bad in ["../up", "a\\\\b", ".hidden", "  "] {
            let (src, name) = named(&format!("\nname = \"{bad}\"\n"), "c.toml");
            let err = src.run_name(name.as_ref(), "x").unwrap_err().to_string();
            assert_eq!(
                err,
                format!(
                    "c.toml:2:8: name: must be a plain file name (no slashes, not empty, not \
                     starting with '.') (got \"{}\")",
                    bad.replace("\\\\", "\\").trim()
                )
            );
        }
        let (src, name) = named("\n", ".hidden.toml");
        assert!(src.run_name(name.as_ref(), "x").is_err());
    }
}
