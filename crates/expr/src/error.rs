use std::ops::Range;

use thiserror::Error;

/// Everything that can go wrong while parsing, compiling or evaluating an expression.
///
/// Spans are 0-based *character* (not byte) offsets into the expression's source, so that a
/// caller can underline them in a terminal; an empty span `n..n` points just after the last
/// character (the end of the input). [`ExprError::span`] and [`ExprError::column`] give the
/// position without matching on the variant; the caller adds the file and line.
#[non_exhaustive]
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum ExprError {
    /// The source is empty or only whitespace.
    #[error("empty expression")]
    Empty,
    /// A token (or the end of the input) where something else was required.
    #[error("expected {expected}, found {}", found_text(.found))]
    UnexpectedToken {
        /// Where the token is (`n..n` at the end of the input).
        span: Range<usize>,
        /// The token's text, empty for the end of the input.
        found: String,
        /// What the grammar allows there, as a phrase ("a number, a name or `(`").
        expected: &'static str,
    },
    /// A parenthesis without its partner.
    #[error("{}", paren_text(*.paren))]
    UnbalancedParen {
        /// The parenthesis that has no partner.
        span: Range<usize>,
        /// `'('` for an opening parenthesis never closed, `')'` for a closing one never opened.
        paren: char,
    },
    /// A number that does not parse, or overflows to infinity (`1e400`, `1.2.3`, `2x`, `1e`).
    #[error("invalid number `{text}`")]
    InvalidNumber {
        /// The number's characters.
        span: Range<usize>,
        /// Its text.
        text: String,
    },
    /// A call of a name that is not a function.
    #[error("unknown function `{name}`{}", suggestion_text(.suggestion))]
    UnknownFunction {
        /// The name.
        span: Range<usize>,
        /// The name as written.
        name: String,
        /// The closest function name, if one is close: edit distance at most 2 and at most a
        /// third of the name's length (but at least 1, and less than the whole name).
        suggestion: Option<String>,
    },
    /// A function called with the wrong number of arguments.
    #[error("`{name}` takes {expected} argument{}, found {found}", plural(*.expected))]
    WrongArity {
        /// The function's name.
        span: Range<usize>,
        /// The function's name.
        name: String,
        /// Its arity.
        expected: usize,
        /// The number of arguments given.
        found: usize,
    },
    /// A function name used as a value (`sin + 1`).
    #[error("`{name}` is a function: call it with arguments in parentheses, as in `{name}(x)`")]
    FunctionNotCalled {
        /// The name.
        span: Range<usize>,
        /// The function's name.
        name: String,
    },
    /// A variable with no value: not in the layout given to `Program::compile`, or unknown to
    /// the lookup of `Expr::eval_with`.
    #[error("unknown variable `{name}`{}", suggestion_text(.suggestion))]
    UnknownVariable {
        /// Where the variable first appears in its source. Empty (`0..0`) for a variable made by
        /// `Expr::var`, which has no source; [`ExprError::span`] then returns `None`.
        span: Range<usize>,
        /// The name.
        name: String,
        /// The closest name in the layout, if one is close (as for [`ExprError::UnknownFunction`]).
        suggestion: Option<String>,
    },
    /// A name listed twice in the variable layout given to `Program::compile`.
    #[error("variable `{name}` appears twice in the layout (slots {first} and {second})")]
    DuplicateVariable {
        /// The name.
        name: String,
        /// Its first slot.
        first: usize,
        /// Its second slot.
        second: usize,
    },
    /// The expression tree would be deeper than the parser allows. The limit keeps hostile input
    /// (ten thousand `(`, or a sum of a hundred thousand terms) from overflowing the stack of the
    /// recursive algorithms.
    #[error("expression nested deeper than {depth} levels")]
    TooDeep {
        /// The limit that was exceeded.
        depth: usize,
    },
}

impl ExprError {
    /// Where in the expression's source the error is, as 0-based character offsets, if it has a
    /// position.
    pub fn span(&self) -> Option<Range<usize>> {
        match self {
            ExprError::UnexpectedToken { span, .. }
            | ExprError::UnbalancedParen { span, .. }
            | ExprError::InvalidNumber { span, .. }
            | ExprError::UnknownFunction { span, .. }
            | ExprError::WrongArity { span, .. }
            | ExprError::FunctionNotCalled { span, .. } => Some(span.clone()),
            // A variable built by `Expr::var` has no source; its span is the placeholder 0..0.
            ExprError::UnknownVariable { span, .. } => (!span.is_empty()).then(|| span.clone()),
            ExprError::Empty | ExprError::DuplicateVariable { .. } | ExprError::TooDeep { .. } => {
                None
            }
        }
    }

    /// The 1-based column (in characters) where the error starts, if it has a position.
    pub fn column(&self) -> Option<usize> {
        self.span().map(|s| s.start + 1)
    }
}

fn found_text(found: &str) -> String {
    if found.is_empty() {
        "end of input".to_owned()
    } else {
        format!("`{found}`")
    }
}

fn paren_text(paren: char) -> &'static str {
    if paren == '(' {
        "unbalanced parenthesis: this `(` is never closed"
    } else {
        "unbalanced parenthesis: this `)` has no matching `(`"
    }
}

fn suggestion_text(suggestion: &Option<String>) -> String {
    match suggestion {
        Some(s) => format!(" (did you mean `{s}`?)"),
        None => String::new(),
    }
}

fn plural(n: usize) -> &'static str {
    if n == 1 {
        ""
    } else {
        "s"
    }
}

/// The candidate closest to `name` by edit distance (the first on a tie), if within 2 and
/// within a third of the name's length (at least 1, but less than the length): as in rustc,
/// so that `foo` does not suggest `cos`.
pub(crate) fn suggest<'a>(
    name: &str,
    candidates: impl IntoIterator<Item = &'a str>,
) -> Option<String> {
    let len = name.chars().count();
    // Replacing every character of a name is no suggestion (`q` for `x`).
    let limit = (len / 3).clamp(1, 2).min(len.saturating_sub(1));
    let mut best: Option<(usize, &str)> = None;
    for c in candidates {
        let d = levenshtein(name, c);
        if d <= limit && best.map_or(true, |(bd, _)| d < bd) {
            best = Some((d, c));
        }
    }
    best.map(|(_, c)| c.to_owned())
}

fn levenshtein(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diag = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let up = row[j + 1];
            row[j + 1] = (diag + usize::from(ca != cb)).min(row[j] + 1).min(up + 1);
            diag = up;
        }
    }
    row[b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edit_distance() {
        assert_eq!(levenshtein("kk", "k"), 1);
        assert_eq!(levenshtein("sine", "sin"), 1);
        assert_eq!(levenshtein("", "abc"), 3);
        assert_eq!(levenshtein("kitten", "sitting"), 3);
        assert_eq!(suggest("kk", ["m", "k", "kx"]), Some("k".to_owned()));
        assert_eq!(suggest("zzzz", ["m", "k"]), None);
    }
}
