//! The APDL expression evaluator used for every numeric field.
//!
//! Grammar (Fortran precedence, as ANSYS reads it):
//!
//! ```text
//! expr    = term { ("+" | "-") term }
//! term    = unary { ("*" | "/") unary }
//! unary   = ("+" | "-") unary | power
//! power   = primary [ "**" unary ]          (right-associative, binds tighter than a sign)
//! primary = number | NAME | NAME "(" expr { "," expr } ")" | "(" expr ")"
//! ```
//!
//! So `-2**2 = -4`, `2**3**2 = 512` and `2*-3 = -6`. Names are case-insensitive parameters or the
//! functions `SIN COS TAN ASIN ACOS ATAN ATAN2(y,x) SQRT ABS EXP LOG LOG10 SINH COSH TANH NINT
//! SIGN(a,b) MOD(a,b) MIN(..) MAX(..)`. `LOG` is the natural logarithm. The trigonometric
//! functions take (and the inverse ones return) radians unless `*AFUN,DEG` is in effect
//! ([`AngleUnit`]). There is no predefined `PI`: ANSYS has none, decks write `ACOS(-1)`.
//! Nesting is capped at [`MAX_DEPTH`] so that no input can overflow the stack.

use std::collections::BTreeMap;

/// The deepest nesting of parentheses, signs and exponents an expression may have.
pub const MAX_DEPTH: usize = 64;

/// The angle unit of the trigonometric functions (`*AFUN`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[doc(alias = "*AFUN")]
pub enum AngleUnit {
    /// Radians (`*AFUN,RAD`, the ANSYS default).
    #[default]
    Radians,
    /// Degrees (`*AFUN,DEG`).
    Degrees,
}

/// Why an expression could not be evaluated.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ExprError {
    /// Not an expression: the reason says what was expected.
    #[error("{0}")]
    Malformed(String),
    /// Nested deeper than [`MAX_DEPTH`].
    #[error("nested deeper than {MAX_DEPTH} levels")]
    TooDeep,
    /// A name that is neither a parameter nor a function.
    #[error("unknown parameter `{0}`")]
    UnknownParameter(String),
    /// The value is infinite or NaN.
    #[error("not a finite number")]
    NonFinite,
}

/// Evaluates `text` with the parameters `params` (keys upper case) and the angle unit `unit`.
///
/// ```
/// use std::collections::BTreeMap;
/// use rapier3d_mpc184::deck::{AngleUnit, evaluate};
/// let mut p = BTreeMap::new();
/// p.insert("L".to_string(), 2.0);
/// assert_eq!(evaluate("-l**2/4", &p, AngleUnit::Radians), Ok(-1.0));
/// assert_eq!(evaluate("ASIN(1)", &p, AngleUnit::Degrees), Ok(90.0));
/// ```
pub fn evaluate(
    text: &str,
    params: &BTreeMap<String, f64>,
    unit: AngleUnit,
) -> Result<f64, ExprError> {
    let tokens = tokenize(text)?;
    let mut p = Parser {
        tokens: &tokens,
        pos: 0,
        params,
        unit,
        depth: 0,
    };
    let v = p.expr()?;
    if let Some(t) = p.peek() {
        return Err(ExprError::Malformed(format!(
            "unexpected {} after the expression",
            t.describe()
        )));
    }
    if v.is_finite() {
        Ok(v)
    } else {
        Err(ExprError::NonFinite)
    }
}

#[derive(Clone, Debug, PartialEq)]
enum Token {
    Num(f64),
    Name(String),
    Plus,
    Minus,
    Star,
    Slash,
    Pow,
    Open,
    Close,
    Comma,
}

impl Token {
    fn describe(&self) -> String {
        match self {
            Token::Num(v) => format!("number {v}"),
            Token::Name(n) => format!("name `{n}`"),
            Token::Plus => "`+`".into(),
            Token::Minus => "`-`".into(),
            Token::Star => "`*`".into(),
            Token::Slash => "`/`".into(),
            Token::Pow => "`**`".into(),
            Token::Open => "`(`".into(),
            Token::Close => "`)`".into(),
            Token::Comma => "`,`".into(),
        }
    }
}

fn tokenize(text: &str) -> Result<Vec<Token>, ExprError> {
    let chars: Vec<char> = text.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while let Some(&c) = chars.get(i) {
        match c {
            ' ' | '\t' => i += 1,
            '+' => {
                out.push(Token::Plus);
                i += 1;
            }
            '-' => {
                out.push(Token::Minus);
                i += 1;
            }
            '*' if chars.get(i + 1) == Some(&'*') => {
                out.push(Token::Pow);
                i += 2;
            }
            '*' => {
                out.push(Token::Star);
                i += 1;
            }
            '/' => {
                out.push(Token::Slash);
                i += 1;
            }
            '(' => {
                out.push(Token::Open);
                i += 1;
            }
            ')' => {
                out.push(Token::Close);
                i += 1;
            }
            ',' => {
                out.push(Token::Comma);
                i += 1;
            }
            c if c.is_ascii_digit() || c == '.' => {
                let start = i;
                while chars
                    .get(i)
                    .is_some_and(|c| c.is_ascii_digit() || *c == '.')
                {
                    i += 1;
                }
                if chars.get(i).is_some_and(|c| matches!(c, 'e' | 'E')) {
                    let mut j = i + 1;
                    if chars.get(j).is_some_and(|c| matches!(c, '+' | '-')) {
                        j += 1;
                    }
                    if chars.get(j).is_some_and(char::is_ascii_digit) {
                        i = j;
                        while chars.get(i).is_some_and(char::is_ascii_digit) {
                            i += 1;
                        }
                    }
                }
                let s: String = chars.get(start..i).unwrap_or_default().iter().collect();
                let v: f64 = s
                    .parse()
                    .map_err(|_| ExprError::Malformed(format!("`{s}` is not a number")))?;
                out.push(Token::Num(v));
            }
            c if c.is_ascii_alphabetic() || c == '_' => {
                let start = i;
                while chars
                    .get(i)
                    .is_some_and(|c| c.is_ascii_alphanumeric() || *c == '_')
                {
                    i += 1;
                }
                let s: String = chars.get(start..i).unwrap_or_default().iter().collect();
                out.push(Token::Name(s.to_ascii_uppercase()));
            }
            other => {
                return Err(ExprError::Malformed(format!(
                    "unexpected character `{other}`"
                )));
            }
        }
    }
    if out.is_empty() {
        return Err(ExprError::Malformed("empty expression".into()));
    }
    Ok(out)
}

struct Parser<'a> {
    tokens: &'a [Token],
    pos: usize,
    params: &'a BTreeMap<String, f64>,
    unit: AngleUnit,
    depth: usize,
}

impl Parser<'_> {
    fn peek(&self) -> Option<&Token> {
        self.tokens.get(self.pos)
    }

    fn next(&mut self) -> Option<Token> {
        let t = self.tokens.get(self.pos).cloned();
        self.pos += 1;
        t
    }

    fn enter(&mut self) -> Result<(), ExprError> {
        self.depth += 1;
        if self.depth > MAX_DEPTH {
            Err(ExprError::TooDeep)
        } else {
            Ok(())
        }
    }

    fn expr(&mut self) -> Result<f64, ExprError> {
        let mut v = self.term()?;
        loop {
            match self.peek() {
                Some(Token::Plus) => {
                    self.pos += 1;
                    v += self.term()?;
                }
                Some(Token::Minus) => {
                    self.pos += 1;
                    v -= self.term()?;
                }
                _ => return Ok(v),
            }
        }
    }

    fn term(&mut self) -> Result<f64, ExprError> {
        let mut v = self.unary()?;
        loop {
            match self.peek() {
                Some(Token::Star) => {
                    self.pos += 1;
                    v *= self.unary()?;
                }
                Some(Token::Slash) => {
                    self.pos += 1;
                    v /= self.unary()?;
                }
                _ => return Ok(v),
            }
        }
    }

    fn unary(&mut self) -> Result<f64, ExprError> {
        self.enter()?;
        let v = match self.peek() {
            Some(Token::Minus) => {
                self.pos += 1;
                -self.unary()?
            }
            Some(Token::Plus) => {
                self.pos += 1;
                self.unary()?
            }
            _ => self.power()?,
        };
        self.depth -= 1;
        Ok(v)
    }

    fn power(&mut self) -> Result<f64, ExprError> {
        let base = self.primary()?;
        if self.peek() == Some(&Token::Pow) {
            self.pos += 1;
            let exponent = self.unary()?;
            Ok(base.powf(exponent))
        } else {
            Ok(base)
        }
    }

    fn primary(&mut self) -> Result<f64, ExprError> {
        match self.next() {
            Some(Token::Num(v)) => Ok(v),
            Some(Token::Open) => {
                self.enter()?;
                let v = self.expr()?;
                self.expect_close()?;
                self.depth -= 1;
                Ok(v)
            }
            Some(Token::Name(name)) => {
                if self.peek() == Some(&Token::Open) {
                    self.pos += 1;
                    self.enter()?;
                    let mut args = vec![self.expr()?];
                    while self.peek() == Some(&Token::Comma) {
                        self.pos += 1;
                        args.push(self.expr()?);
                    }
                    self.expect_close()?;
                    self.depth -= 1;
                    self.call(&name, &args)
                } else {
                    self.params
                        .get(&name)
                        .copied()
                        .ok_or(ExprError::UnknownParameter(name))
                }
            }
            Some(t) => Err(ExprError::Malformed(format!(
                "expected a number, a name or `(`, found {}",
                t.describe()
            ))),
            None => Err(ExprError::Malformed(
                "the expression ends where a value was expected".into(),
            )),
        }
    }

    fn expect_close(&mut self) -> Result<(), ExprError> {
        match self.next() {
            Some(Token::Close) => Ok(()),
            Some(t) => Err(ExprError::Malformed(format!(
                "expected `)`, found {}",
                t.describe()
            ))),
            None => Err(ExprError::Malformed("missing `)`".into())),
        }
    }

    fn call(&self, name: &str, args: &[f64]) -> Result<f64, ExprError> {
        let (to_rad, from_rad) = match self.unit {
            AngleUnit::Radians => (1.0, 1.0),
            AngleUnit::Degrees => (core::f64::consts::PI / 180.0, 180.0 / core::f64::consts::PI),
        };
        let arity = |n: usize| -> Result<(), ExprError> {
            if args.len() == n {
                Ok(())
            } else {
                Err(ExprError::Malformed(format!(
                    "{name} takes {n} argument(s), {} given",
                    args.len()
                )))
            }
        };
        let a = args.first().copied().unwrap_or(0.0);
        let b = args.get(1).copied().unwrap_or(0.0);
        let unary = |f: fn(f64) -> f64| -> Result<f64, ExprError> {
            arity(1)?;
            Ok(f(a))
        };
        match name {
            "SIN" => unary(|x| x).map(|x| (x * to_rad).sin()),
            "COS" => unary(|x| x).map(|x| (x * to_rad).cos()),
            "TAN" => unary(|x| x).map(|x| (x * to_rad).tan()),
            "ASIN" => unary(f64::asin).map(|v| v * from_rad),
            "ACOS" => unary(f64::acos).map(|v| v * from_rad),
            "ATAN" => unary(f64::atan).map(|v| v * from_rad),
            "ATAN2" => {
                arity(2)?;
                Ok(a.atan2(b) * from_rad)
            }
            "SQRT" => unary(f64::sqrt),
            "ABS" => unary(f64::abs),
            "EXP" => unary(f64::exp),
            "LOG" => unary(f64::ln),
            "LOG10" => unary(f64::log10),
            "SINH" => unary(f64::sinh),
            "COSH" => unary(f64::cosh),
            "TANH" => unary(f64::tanh),
            "NINT" => unary(f64::round),
            "SIGN" => {
                arity(2)?;
                Ok(if b < 0.0 { -a.abs() } else { a.abs() })
            }
            "MOD" => {
                arity(2)?;
                Ok(a % b)
            }
            "MIN" | "MAX" => {
                if args.is_empty() {
                    return Err(ExprError::Malformed(format!("{name} needs arguments")));
                }
                let pick = if name == "MIN" { f64::min } else { f64::max };
                Ok(args.iter().copied().fold(a, pick))
            }
            _ => Err(ExprError::Malformed(format!(
                "`{name}` is not a function this reader knows (SIN COS TAN ASIN ACOS ATAN ATAN2 \
                 SQRT ABS EXP LOG LOG10 SINH COSH TANH NINT SIGN MOD MIN MAX)"
            ))),
        }
    }
}
