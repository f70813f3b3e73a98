//! Reading a model from TOML: every key and value keeps its position in the file, so that a
//! mistake anywhere, inside an expression too, is reported with file, line and column.

use std::path::{Path, PathBuf};

use toml_edit::{ImDocument, Item, TableLike, Value};

use crate::error::{Location, ModelError};

/// The model's source text, for turning byte offsets into lines and columns.
#[derive(Debug, Clone)]
pub(crate) struct Source {
    pub path: Option<PathBuf>,
    pub text: String,
}

impl Source {
    pub fn location(&self, byte: Option<usize>) -> Location {
        let Some(byte) = byte else {
            return Location {
                path: self.path.clone(),
                line: None,
                column: None,
            };
        };
        let byte = byte.min(self.text.len());
        let before = &self.text[..byte];
        let line = before.bytes().filter(|&b| b == b'\n').count() + 1;
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        let column = self.text[line_start..byte].chars().count() + 1;
        Location {
            path: self.path.clone(),
            line: Some(line),
            column: Some(column),
        }
    }

    pub fn invalid(&self, at: Option<usize>, key: &str, message: impl Into<String>) -> ModelError {
        ModelError::Invalid {
            location: self.location(at),
            key: key.to_string(),
            message: message.into(),
        }
    }
}

/// An expression as written: its text, its key path, and the byte offset of its first
/// character in the file (`None` for expressions that did not come from a file).
#[derive(Debug, Clone)]
pub(crate) struct ExprSrc {
    pub text: String,
    pub key: String,
    pub at: Option<usize>,
}

/// `name = "expression"` pairs in file order.
pub(crate) type Equations = Vec<(String, ExprSrc)>;
/// A mode: its name, its equations and where it starts.
pub(crate) type ModeSpec = (String, Equations, Option<usize>);
/// A state: its name, its unit and where it is declared.
pub(crate) type StateSpec = (String, Option<String>, Option<usize>);
/// A name and where it is written.
pub(crate) type Named = (String, Option<usize>);
/// A state's starting value and where it is written.
pub(crate) type StartValue = (String, f64, Option<usize>);

#[derive(Debug, Clone)]
pub(crate) struct ParamSpec {
    pub name: String,
    pub value: f64,
    pub unit: Option<String>,
    pub min: f64,
    pub max: f64,
    pub free: bool,
    pub at: Option<usize>,
}

#[derive(Debug, Clone)]
pub(crate) struct GuardSpec {
    pub key: String,
    pub name: Option<String>,
    pub from: Option<(String, Option<usize>)>,
    pub to: Option<(String, Option<usize>)>,
    pub when: ExprSrc,
    pub direction: (String, Option<usize>),
    pub reset: Vec<(String, ExprSrc)>,
    pub at: Option<usize>,
}

#[derive(Debug, Clone)]
pub(crate) struct OutputSpec {
    pub name: String,
    pub expr: ExprSrc,
    pub unit: Option<String>,
}

/// A model as written, names not yet resolved.
#[derive(Debug, Clone)]
pub(crate) struct Spec {
    pub name: String,
    pub description: Option<String>,
    pub states: Vec<StateSpec>,
    pub params: Vec<ParamSpec>,
    pub input: (String, Option<String>),
    pub period: Option<ExprSrc>,
    pub signals: Vec<(String, ExprSrc)>,
    pub definitions: Vec<(String, ExprSrc)>,
    pub flow: Vec<(String, ExprSrc)>,
    pub modes: Vec<ModeSpec>,
    pub guards: Vec<GuardSpec>,
    pub outputs: Vec<OutputSpec>,
    pub initial_mode: Option<Named>,
    pub initial_state: Vec<StartValue>,
    pub at: Option<usize>,
}

const TOP_KEYS: &[&str] = &[
    "name",
    "description",
    "states",
    "parameters",
    "input",
    "forcing",
    "definitions",
    "flow",
    "modes",
    "guards",
    "outputs",
    "initial",
];

/// Parses `text` and reads the model in the table at `table_path` (empty: the whole document).
pub(crate) fn read(
    text: &str,
    path: Option<&Path>,
    table_path: &[&str],
) -> Result<(Spec, Source), ModelError> {
    let src = Source {
        path: path.map(Path::to_path_buf),
        text: text.to_string(),
    };
    let doc = ImDocument::parse(text.to_string()).map_err(|e| ModelError::Toml {
        location: src.location(e.span().map(|s| s.start)),
        message: e.message().to_string(),
    })?;
    let mut table: &dyn TableLike = doc.as_table();
    let mut prefix = String::new();
    for part in table_path {
        let item = table
            .get(part)
            .ok_or_else(|| src.invalid(None, part, "missing table"))?;
        prefix = if prefix.is_empty() {
            (*part).to_string()
        } else {
            format!("{prefix}.{part}")
        };
        table = item
            .as_table_like()
            .ok_or_else(|| src.invalid(item.span().map(|s| s.start), &prefix, "must be a table"))?;
    }
    let spec = Reader {
        src: &src,
        prefix: &prefix,
    }
    .model(table)?;
    Ok((spec, src))
}

struct Reader<'a> {
    src: &'a Source,
    prefix: &'a str,
}

fn start(item: &Item) -> Option<usize> {
    item.span().map(|s| s.start)
}

/// Offset of the first character inside a string value's quotes.
fn content_start(text: &str, value: &Value) -> Option<usize> {
    let span = value.span()?;
    let raw = &text[span.start..span.end.min(text.len())];
    let skip = if raw.starts_with("\"\"\"") || raw.starts_with("'''") {
        3
    } else {
        1
    };
    Some(span.start + skip)
}

fn suggest<'b>(name: &str, choices: impl IntoIterator<Item = &'b str>) -> String {
    let best = choices
        .into_iter()
        .map(|c| (edit_distance(name, c), c))
        .filter(|(d, _)| *d <= 2)
        .min_by_key(|(d, _)| *d);
    match best {
        Some((_, c)) => format!(" (did you mean `{c}`?)"),
        None => String::new(),
    }
}

pub(crate) fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut prev = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let cur = row[j + 1];
            row[j + 1] = (row[j + 1] + 1)
                .min(row[j] + 1)
                .min(prev + usize::from(ca != cb));
            prev = cur;
        }
    }
    row[b.len()]
}

impl Reader<'_> {
    fn key(&self, k: &str) -> String {
        if self.prefix.is_empty() {
            k.to_string()
        } else {
            format!("{}.{k}", self.prefix)
        }
    }

    fn err(&self, at: Option<usize>, key: &str, msg: impl Into<String>) -> ModelError {
        self.src.invalid(at, key, msg)
    }

    fn check_keys(
        &self,
        table: &dyn TableLike,
        allowed: &[&str],
        key: &str,
    ) -> Result<(), ModelError> {
        for (k, item) in table.iter() {
            if !allowed.contains(&k) {
                let path = if key.is_empty() {
                    k.to_string()
                } else {
                    format!("{key}.{k}")
                };
                return Err(self.err(
                    start(item),
                    &path,
                    format!(
                        "unknown key{}; allowed here: {}",
                        suggest(k, allowed.iter().copied()),
                        allowed.join(", ")
                    ),
                ));
            }
        }
        Ok(())
    }

    fn string(&self, item: &Item, key: &str) -> Result<(String, Option<usize>), ModelError> {
        match item.as_value() {
            Some(Value::String(s)) => Ok((s.value().clone(), start(item))),
            _ => Err(self.err(start(item), key, "must be a string")),
        }
    }

    fn number(&self, item: &Item, key: &str) -> Result<f64, ModelError> {
        let v = match item.as_value() {
            Some(Value::Float(f)) => *f.value(),
            Some(Value::Integer(i)) => *i.value() as f64,
            _ => return Err(self.err(start(item), key, "must be a number")),
        };
        if v.is_nan() {
            return Err(self.err(start(item), key, "must be a number (got nan)"));
        }
        Ok(v)
    }

    fn expr(&self, item: &Item, key: &str) -> Result<ExprSrc, ModelError> {
        match item.as_value() {
            Some(v @ Value::String(s)) => Ok(ExprSrc {
                text: s.value().clone(),
                key: key.to_string(),
                at: content_start(&self.src.text, v),
            }),
            // A bare number is a constant expression.
            Some(Value::Float(f)) => Ok(ExprSrc {
                text: format!("{:e}", f.value()),
                key: key.to_string(),
                at: start(item),
            }),
            Some(Value::Integer(i)) => Ok(ExprSrc {
                text: i.value().to_string(),
                key: key.to_string(),
                at: start(item),
            }),
            _ => Err(self.err(
                start(item),
                key,
                "must be an expression in quotes, e.g. \"-k*x\"",
            )),
        }
    }

    fn table<'b>(&self, item: &'b Item, key: &str) -> Result<&'b dyn TableLike, ModelError> {
        item.as_table_like()
            .ok_or_else(|| self.err(start(item), key, "must be a table"))
    }

    /// A table of `name = "expression"` pairs, in file order.
    fn expr_table(&self, item: &Item, key: &str) -> Result<Equations, ModelError> {
        let t = self.table(item, key)?;
        t.iter()
            .map(|(k, v)| Ok((k.to_string(), self.expr(v, &format!("{key}.{k}"))?)))
            .collect()
    }

    fn model(&self, t: &dyn TableLike) -> Result<Spec, ModelError> {
        self.check_keys(t, TOP_KEYS, self.prefix)?;
        let get = |k: &str| t.get(k);
        let at = t.iter().next().and_then(|(_, i)| start(i));
        let name = match get("name") {
            Some(i) => self.string(i, &self.key("name"))?.0,
            None => "model".to_string(),
        };
        let description = match get("description") {
            Some(i) => Some(self.string(i, &self.key("description"))?.0),
            None => None,
        };
        let states = self.states(get("states"), at)?;
        let params = match get("parameters") {
            Some(i) => self.params(i)?,
            None => Vec::new(),
        };
        let input = match get("input") {
            Some(i) => self.input(i)?,
            None => ("u".to_string(), None),
        };
        let (period, signals) = match get("forcing") {
            Some(i) => self.forcing(i)?,
            None => (None, Vec::new()),
        };
        let definitions = match get("definitions") {
            Some(i) => self.expr_table(i, &self.key("definitions"))?,
            None => Vec::new(),
        };
        let flow = match get("flow") {
            Some(i) => self.expr_table(i, &self.key("flow"))?,
            None => Vec::new(),
        };
        let modes = match get("modes") {
            Some(i) => {
                let key = self.key("modes");
                let mt = self.table(i, &key)?;
                let mut modes = Vec::new();
                for (name, item) in mt.iter() {
                    let k = format!("{key}.{name}");
                    modes.push((name.to_string(), self.expr_table(item, &k)?, start(item)));
                }
                modes
            }
            None => Vec::new(),
        };
        let guards = match get("guards") {
            Some(i) => self.guards(i)?,
            None => Vec::new(),
        };
        let outputs = match get("outputs") {
            Some(i) => self.outputs(i)?,
            None => Vec::new(),
        };
        let (initial_mode, initial_state) = match get("initial") {
            Some(i) => self.initial(i)?,
            None => (None, Vec::new()),
        };
        Ok(Spec {
            name,
            description,
            states,
            params,
            input,
            period,
            signals,
            definitions,
            flow,
            modes,
            guards,
            outputs,
            initial_mode,
            initial_state,
            at,
        })
    }

    fn states(&self, item: Option<&Item>, at: Option<usize>) -> Result<Vec<StateSpec>, ModelError> {
        let key = self.key("states");
        let Some(item) = item else {
            return Err(self.err(
                at,
                &key,
                "missing: list the state names, e.g. states = [\"x\", \"v\"]",
            ));
        };
        let Some(arr) = item.as_array() else {
            return Err(self.err(
                start(item),
                &key,
                "must be a list of names, e.g. [\"x\", \"v\"], or of tables {name = \"x\", unit = \"m\"}",
            ));
        };
        let mut out = Vec::new();
        for (i, v) in arr.iter().enumerate() {
            let k = format!("{key}[{i}]");
            let pos = v.span().map(|s| s.start);
            match v {
                Value::String(s) => out.push((s.value().clone(), None, pos)),
                Value::InlineTable(t) => {
                    let t: &dyn TableLike = t;
                    self.check_keys(t, &["name", "unit"], &k)?;
                    let name = match t.get("name") {
                        Some(n) => self.string(n, &format!("{k}.name"))?.0,
                        None => return Err(self.err(pos, &k, "needs a name")),
                    };
                    let unit = match t.get("unit") {
                        Some(u) => Some(self.string(u, &format!("{k}.unit"))?.0),
                        None => None,
                    };
                    out.push((name, unit, pos));
                }
                _ => {
                    return Err(self.err(
                        pos,
                        &k,
                        "must be a name in quotes or a table {name = \"x\", unit = \"m\"}",
                    ))
                }
            }
        }
        if out.is_empty() {
            return Err(self.err(start(item), &key, "needs at least one state"));
        }
        Ok(out)
    }

    fn params(&self, item: &Item) -> Result<Vec<ParamSpec>, ModelError> {
        let key = self.key("parameters");
        let t = self.table(item, &key)?;
        let mut out = Vec::new();
        for (name, item) in t.iter() {
            let k = format!("{key}.{name}");
            let at = start(item);
            let mut p = ParamSpec {
                name: name.to_string(),
                value: 0.0,
                unit: None,
                min: f64::NEG_INFINITY,
                max: f64::INFINITY,
                free: false,
                at,
            };
            if let Some(pt) = item.as_table_like() {
                self.check_keys(pt, &["value", "unit", "min", "max", "free"], &k)?;
                p.value = match pt.get("value") {
                    Some(v) => self.number(v, &format!("{k}.value"))?,
                    None => return Err(self.err(at, &k, "needs a value")),
                };
                if let Some(u) = pt.get("unit") {
                    p.unit = Some(self.string(u, &format!("{k}.unit"))?.0);
                }
                if let Some(v) = pt.get("min") {
                    p.min = self.number(v, &format!("{k}.min"))?;
                }
                if let Some(v) = pt.get("max") {
                    p.max = self.number(v, &format!("{k}.max"))?;
                }
                if let Some(v) = pt.get("free") {
                    p.free = v.as_bool().ok_or_else(|| {
                        self.err(start(v), &format!("{k}.free"), "must be true or false")
                    })?;
                }
            } else {
                p.value = self.number(item, &k).map_err(|_| {
                    self.err(
                        at,
                        &k,
                        "must be a number or a table {value = 1.0, unit = \"kg\", min = 0, max = 10, free = true}",
                    )
                })?;
            }
            if !p.value.is_finite() {
                return Err(self.err(at, &k, format!("must be finite (got {})", p.value)));
            }
            if p.min > p.max {
                return Err(self.err(at, &k, format!("min ({}) is above max ({})", p.min, p.max)));
            }
            if p.value < p.min || p.value > p.max {
                return Err(self.err(
                    at,
                    &k,
                    format!(
                        "value {} is outside its bounds [{}, {}]",
                        p.value, p.min, p.max
                    ),
                ));
            }
            out.push(p);
        }
        Ok(out)
    }

    fn input(&self, item: &Item) -> Result<(String, Option<String>), ModelError> {
        let key = self.key("input");
        let t = self.table(item, &key)?;
        self.check_keys(t, &["name", "unit"], &key)?;
        let name = match t.get("name") {
            Some(n) => self.string(n, &format!("{key}.name"))?.0,
            None => "u".to_string(),
        };
        let unit = match t.get("unit") {
            Some(u) => Some(self.string(u, &format!("{key}.unit"))?.0),
            None => None,
        };
        Ok((name, unit))
    }

    fn forcing(&self, item: &Item) -> Result<(Option<ExprSrc>, Equations), ModelError> {
        let key = self.key("forcing");
        let t = self.table(item, &key)?;
        self.check_keys(t, &["period", "signals"], &key)?;
        let period = match t.get("period") {
            Some(p) => self.expr(p, &format!("{key}.period"))?,
            None => {
                return Err(self.err(
                    start(item),
                    &key,
                    "needs a period (a number or an expression of parameters)",
                ))
            }
        };
        let signals = match t.get("signals") {
            Some(s) => self.expr_table(s, &format!("{key}.signals"))?,
            None => Vec::new(),
        };
        Ok((Some(period), signals))
    }

    fn guards(&self, item: &Item) -> Result<Vec<GuardSpec>, ModelError> {
        let key = self.key("guards");
        let tables: Vec<(&dyn TableLike, Option<usize>)> = match item {
            Item::ArrayOfTables(a) => a
                .iter()
                .map(|t| (t as &dyn TableLike, t.span().map(|s| s.start)))
                .collect(),
            Item::Value(Value::Array(a)) => {
                let mut v = Vec::new();
                for x in a.iter() {
                    match x {
                        Value::InlineTable(t) => {
                            v.push((t as &dyn TableLike, x.span().map(|s| s.start)))
                        }
                        _ => {
                            return Err(self.err(
                                x.span().map(|s| s.start),
                                &key,
                                "each guard must be a table ([[guards]])",
                            ))
                        }
                    }
                }
                v
            }
            _ => {
                return Err(self.err(
                    start(item),
                    &key,
                    "must be a list of tables: write each guard as [[guards]]",
                ))
            }
        };
        let mut out = Vec::new();
        for (i, (t, at)) in tables.into_iter().enumerate() {
            let k = format!("{key}[{i}]");
            self.check_keys(t, &["name", "from", "to", "when", "direction", "reset"], &k)?;
            let name = match t.get("name") {
                Some(n) => Some(self.string(n, &format!("{k}.name"))?.0),
                None => None,
            };
            let from = match t.get("from") {
                Some(n) => Some(self.string(n, &format!("{k}.from"))?),
                None => None,
            };
            let to = match t.get("to") {
                Some(n) => Some(self.string(n, &format!("{k}.to"))?),
                None => None,
            };
            let when = match t.get("when") {
                Some(w) => self.expr(w, &format!("{k}.when"))?,
                None => {
                    return Err(self.err(
                        at,
                        &k,
                        "needs `when`: the expression whose zero crossing triggers the guard",
                    ))
                }
            };
            let direction = match t.get("direction") {
                Some(d) => self.string(d, &format!("{k}.direction"))?,
                None => ("either".to_string(), at),
            };
            let reset = match t.get("reset") {
                Some(r) => self.expr_table(r, &format!("{k}.reset"))?,
                None => Vec::new(),
            };
            out.push(GuardSpec {
                key: k,
                name,
                from,
                to,
                when,
                direction,
                reset,
                at,
            });
        }
        Ok(out)
    }

    fn outputs(&self, item: &Item) -> Result<Vec<OutputSpec>, ModelError> {
        let key = self.key("outputs");
        let t = self.table(item, &key)?;
        let mut out = Vec::new();
        for (name, item) in t.iter() {
            let k = format!("{key}.{name}");
            if let Some(ot) = item.as_table_like() {
                self.check_keys(ot, &["expr", "unit"], &k)?;
                let expr = match ot.get("expr") {
                    Some(e) => self.expr(e, &format!("{k}.expr"))?,
                    None => return Err(self.err(start(item), &k, "needs expr")),
                };
                let unit = match ot.get("unit") {
                    Some(u) => Some(self.string(u, &format!("{k}.unit"))?.0),
                    None => None,
                };
                out.push(OutputSpec {
                    name: name.to_string(),
                    expr,
                    unit,
                });
            } else {
                out.push(OutputSpec {
                    name: name.to_string(),
                    expr: self.expr(item, &k)?,
                    unit: None,
                });
            }
        }
        Ok(out)
    }

    fn initial(&self, item: &Item) -> Result<(Option<Named>, Vec<StartValue>), ModelError> {
        let key = self.key("initial");
        let t = self.table(item, &key)?;
        let mut mode = None;
        let mut state = Vec::new();
        for (k, v) in t.iter() {
            let kk = format!("{key}.{k}");
            if k == "mode" {
                mode = Some(self.string(v, &kk)?);
            } else {
                let x = self.number(v, &kk)?;
                if !x.is_finite() {
                    return Err(self.err(start(v), &kk, format!("must be finite (got {x})")));
                }
                state.push((k.to_string(), x, start(v)));
            }
        }
        Ok((mode, state))
    }
}

pub(crate) fn suggestion<'b>(name: &str, choices: impl IntoIterator<Item = &'b str>) -> String {
    suggest(name, choices)
}
