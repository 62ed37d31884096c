//! pbrt-v4's tokens, and the parameter lists of its directives.
use crate::error::Result;
use crate::scene::import::{At, syntax};
use glam::DVec3;
use std::path::PathBuf;
use std::rc::Rc;

/// Most values in one parameter (a mesh's vertices, say), against hostile files: 2^28.
const MAX_VALUES: usize = 1 << 28;

#[derive(Clone, Debug, PartialEq)]
pub(super) enum Token {
    /// A directive or a bare word (`true`, `false`).
    Word(String),
    Text(String),
    Number(f64),
    Open,
    Close,
}

/// The tokens of a file, each with its line.
pub(super) fn tokenize(text: &str, file: &Rc<PathBuf>) -> Result<Vec<(Token, u32)>> {
    let bytes = text.as_bytes();
    let mut tokens = Vec::new();
    let (mut i, mut line) = (0usize, 1u32);
    while i < bytes.len() {
        let c = bytes[i];
        let at = || At { file: file.clone(), line };
        match c {
            b'\n' => {
                line += 1;
                i += 1;
            }
            _ if c.is_ascii_whitespace() => i += 1,
            b'#' => {
                while i < bytes.len() && bytes[i] != b'\n' {
                    i += 1;
                }
            }
            b'[' => {
                tokens.push((Token::Open, line));
                i += 1;
            }
            b']' => {
                tokens.push((Token::Close, line));
                i += 1;
            }
            b'"' => {
                let start_line = line;
                let mut s = String::new();
                i += 1;
                loop {
                    let Some(&b) = bytes.get(i) else {
                        return Err(syntax(&At { file: file.clone(), line: start_line }, "unterminated string"));
                    };
                    match b {
                        b'"' => break,
                        b'\n' => return Err(syntax(&at(), "a string runs past the end of its line")),
                        b'\\' => {
                            i += 1;
                            match bytes.get(i) {
                                Some(b'n') => s.push('\n'),
                                Some(b't') => s.push('\t'),
                                Some(&e) if e.is_ascii() => s.push(e as char),
                                _ => return Err(syntax(&at(), "a bad escape in a string")),
                            }
                            i += 1;
                        }
                        _ => {
                            // Whole UTF-8 characters (the text is valid UTF-8).
                            let len = text[i..].chars().next().map_or(1, char::len_utf8);
                            s.push_str(&text[i..i + len]);
                            i += len;
                        }
                    }
                }
                i += 1;
                tokens.push((Token::Text(s), start_line));
            }
            _ => {
                let start = i;
                while i < bytes.len() && !bytes[i].is_ascii_whitespace() && !b"[]\"#".contains(&bytes[i]) {
                    i += 1;
                }
                let word = &text[start..i];
                let first = word.as_bytes()[0];
                if first.is_ascii_digit() || b"+-.".contains(&first) {
                    let v: f64 = word.parse().map_err(|_| syntax(&at(), format!("\"{word}\" is not a number")))?;
                    if !v.is_finite() {
                        return Err(syntax(&at(), format!("{word} is not finite")));
                    }
                    tokens.push((Token::Number(v), line));
                } else {
                    tokens.push((Token::Word(word.to_string()), line));
                }
            }
        }
    }
    Ok(tokens)
}

/// A parameter's values.
#[derive(Clone, Debug)]
pub(super) enum Values {
    Numbers(Vec<f64>),
    Texts(Vec<String>),
    Bools(Vec<bool>),
}

/// A parameter: `"type name" value(s)`.
#[derive(Clone, Debug)]
pub(super) struct Param {
    pub(super) kind: String,
    pub(super) name: String,
    pub(super) values: Values,
    pub(super) used: std::cell::Cell<bool>,
}

/// A directive's parameter list.
#[derive(Clone, Debug, Default)]
pub(super) struct Params {
    pub(super) list: Vec<Param>,
}

impl Params {
    pub(super) fn get(&self, name: &str) -> Option<&Param> {
        let p = self.list.iter().rev().find(|p| p.name == name)?;
        p.used.set(true);
        Some(p)
    }

    pub(super) fn numbers(&self, name: &str, at: &At) -> Result<Option<&[f64]>> {
        match self.get(name) {
            None => Ok(None),
            Some(Param { values: Values::Numbers(v), .. }) => Ok(Some(v)),
            Some(p) => Err(syntax(at, format!("\"{} {}\" must hold numbers", p.kind, p.name))),
        }
    }

    pub(super) fn float(&self, name: &str, default: f64, at: &At) -> Result<f64> {
        match self.numbers(name, at)? {
            None => Ok(default),
            Some([v]) => Ok(*v),
            Some(_) => Err(syntax(at, format!("\"{name}\" must be one number"))),
        }
    }

    pub(super) fn integer(&self, name: &str, default: i64, at: &At) -> Result<i64> {
        let v = self.float(name, default as f64, at)?;
        if v.fract() != 0.0 || v.abs() > 1e15 {
            return Err(syntax(at, format!("\"{name}\" must be an integer, got {v}")));
        }
        Ok(v as i64)
    }

    pub(super) fn text(&self, name: &str, at: &At) -> Result<Option<String>> {
        match self.get(name) {
            None => Ok(None),
            Some(Param { values: Values::Texts(v), .. }) if v.len() == 1 => Ok(Some(v[0].clone())),
            Some(p) => Err(syntax(at, format!("\"{} {}\" must be one string", p.kind, p.name))),
        }
    }

    pub(super) fn boolean(&self, name: &str, default: bool, at: &At) -> Result<bool> {
        match self.get(name) {
            None => Ok(default),
            Some(Param { values: Values::Bools(v), .. }) if v.len() == 1 => Ok(v[0]),
            Some(p) => Err(syntax(at, format!("\"{} {}\" must be one bool", p.kind, p.name))),
        }
    }

    pub(super) fn point(&self, name: &str, default: DVec3, at: &At) -> Result<DVec3> {
        match self.numbers(name, at)? {
            None => Ok(default),
            Some([x, y, z]) => Ok(DVec3::new(*x, *y, *z)),
            Some(_) => Err(syntax(at, format!("\"{name}\" must be 3 numbers"))),
        }
    }

    pub(super) fn unused(&self) -> Vec<String> {
        self.list.iter().filter(|p| !p.used.get()).map(|p| format!("\"{} {}\"", p.kind, p.name)).collect()
    }
}

/// A cursor over one file's tokens.
pub(super) struct Cursor<'t> {
    pub(super) tokens: &'t [(Token, u32)],
    pub(super) i: usize,
    pub(super) file: Rc<PathBuf>,
}

impl Cursor<'_> {
    pub(super) fn at(&self) -> At {
        let line = self.tokens.get(self.i.min(self.tokens.len().saturating_sub(1))).map_or(1, |t| t.1);
        At { file: self.file.clone(), line }
    }

    pub(super) fn peek(&self) -> Option<&Token> {
        self.tokens.get(self.i).map(|t| &t.0)
    }

    pub(super) fn next(&mut self) -> Option<Token> {
        let t = self.tokens.get(self.i).map(|t| t.0.clone());
        self.i += 1;
        t
    }

    pub(super) fn number(&mut self, what: &str) -> Result<f64> {
        let at = self.at();
        match self.next() {
            Some(Token::Number(v)) => Ok(v),
            other => Err(syntax(&at, format!("{what}: expected a number, found {}", describe(other.as_ref())))),
        }
    }

    pub(super) fn numbers(&mut self, n: usize, what: &str) -> Result<Vec<f64>> {
        (0..n).map(|_| self.number(what)).collect()
    }

    /// `n` numbers, bare or in brackets.
    pub(super) fn bracketed_numbers(&mut self, n: usize, what: &str) -> Result<Vec<f64>> {
        if self.peek() == Some(&Token::Open) {
            self.next();
            let v = self.numbers(n, what)?;
            let at = self.at();
            return match self.next() {
                Some(Token::Close) => Ok(v),
                other => Err(syntax(&at, format!("{what}: expected ], found {}", describe(other.as_ref())))),
            };
        }
        self.numbers(n, what)
    }

    pub(super) fn text(&mut self, what: &str) -> Result<String> {
        let at = self.at();
        match self.next() {
            Some(Token::Text(s)) => Ok(s),
            other => Err(syntax(&at, format!("{what}: expected a quoted string, found {}", describe(other.as_ref())))),
        }
    }

    /// A parameter list: `"type name" value` pairs up to the next directive.
    pub(super) fn params(&mut self) -> Result<Params> {
        let mut list = Vec::new();
        while let Some(Token::Text(_)) = self.peek() {
            let at = self.at();
            let Some(Token::Text(decl)) = self.next() else { unreachable!() };
            let mut words = decl.split_whitespace();
            let (Some(kind), Some(name), None) = (words.next(), words.next(), words.next()) else {
                return Err(syntax(&at, format!("\"{decl}\" is not a parameter declaration (\"type name\")")));
            };
            let mut items = Vec::new();
            match self.next() {
                Some(Token::Open) => loop {
                    match self.next() {
                        Some(Token::Close) => break,
                        Some(t @ (Token::Number(_) | Token::Text(_) | Token::Word(_))) => {
                            if items.len() >= MAX_VALUES {
                                return Err(syntax(&at, format!("\"{name}\" holds more than {MAX_VALUES} values")));
                            }
                            items.push(t);
                        }
                        other => {
                            return Err(syntax(
                                &at,
                                format!("\"{name}\": expected a value or ], found {}", describe(other.as_ref())),
                            ));
                        }
                    }
                },
                Some(t @ (Token::Number(_) | Token::Text(_) | Token::Word(_))) => items.push(t),
                other => {
                    return Err(syntax(
                        &at,
                        format!("\"{name}\": expected a value, found {}", describe(other.as_ref())),
                    ));
                }
            }
            let values = match kind {
                "bool" => Values::Bools(
                    items
                        .iter()
                        .map(|t| match t {
                            Token::Word(w) | Token::Text(w) if w == "true" => Ok(true),
                            Token::Word(w) | Token::Text(w) if w == "false" => Ok(false),
                            _ => Err(syntax(&at, format!("\"{name}\": a bool is true or false"))),
                        })
                        .collect::<Result<_>>()?,
                ),
                "string" | "texture" => Values::Texts(
                    items
                        .iter()
                        .map(|t| match t {
                            Token::Text(s) => Ok(s.clone()),
                            _ => Err(syntax(&at, format!("\"{name}\": expected quoted strings"))),
                        })
                        .collect::<Result<_>>()?,
                ),
                "spectrum" if matches!(items.first(), Some(Token::Text(_))) => Values::Texts(
                    items
                        .iter()
                        .map(|t| match t {
                            Token::Text(s) => Ok(s.clone()),
                            _ => Err(syntax(&at, format!("\"{name}\": a named spectrum is one string"))),
                        })
                        .collect::<Result<_>>()?,
                ),
                "float" | "integer" | "point" | "point2" | "point3" | "vector" | "vector2" | "vector3" | "normal"
                | "normal3" | "rgb" | "spectrum" | "blackbody" => Values::Numbers(
                    items
                        .iter()
                        .map(|t| match t {
                            Token::Number(v) => Ok(*v),
                            _ => Err(syntax(&at, format!("\"{name}\": expected numbers"))),
                        })
                        .collect::<Result<_>>()?,
                ),
                other => return Err(syntax(&at, format!("\"{other} {name}\": unknown parameter type \"{other}\""))),
            };
            let kind = match kind {
                "point" => "point3",
                "vector" => "vector3",
                "normal" => "normal3",
                k => k,
            };
            list.push(Param { kind: kind.to_string(), name: name.to_string(), values, used: false.into() });
        }
        Ok(Params { list })
    }
}

pub(super) fn describe(t: Option<&Token>) -> String {
    match t {
        None => "the end of the file".into(),
        Some(Token::Word(w)) => w.clone(),
        Some(Token::Text(s)) => format!("\"{s}\""),
        Some(Token::Number(v)) => v.to_string(),
        Some(Token::Open) => "[".into(),
        Some(Token::Close) => "]".into(),
    }
}
