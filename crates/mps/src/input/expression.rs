//! Initial fields written as expressions in a case file (`u = "-omega * y"`), evaluated by the
//! `evalexpr` crate in the coordinates `x`, `y`, `z`, the time `t = 0` and the case's named
//! constants, with the usual functions (`sqrt`, `sin`, `cos`, `tan`, `exp`, `ln`, `abs`,
//! `atan2`, `min`, `max`) and `pi`.
//!
//! Numbers are real: integer literals are read as reals, so `1/2` is 0.5. A bad expression is
//! reported with the position (1-based character) of the fault where it can be found: an
//! unknown name, a missing operator or operand, an unbalanced parenthesis.

use evalexpr::{
    build_operator_tree, ContextWithMutableFunctions, ContextWithMutableVariables,
    DefaultNumericTypes, Function, HashMapContext, Node, Value,
};
use std::collections::BTreeMap;

/// A named function of one real.
type Unary = (&'static str, fn(f64) -> f64);

/// A named function of two reals.
type Binary = (&'static str, fn(f64, f64) -> f64);

/// Functions of one argument available in expressions.
const UNARY: [Unary; 8] = [
    ("sqrt", f64::sqrt),
    ("sin", f64::sin),
    ("cos", f64::cos),
    ("tan", f64::tan),
    ("exp", f64::exp),
    ("ln", f64::ln),
    ("abs", f64::abs),
    ("tanh", f64::tanh),
];

/// Functions of two arguments available in expressions.
const BINARY: [Binary; 3] = [("atan2", f64::atan2), ("min", f64::min), ("max", f64::max)];

/// A fault in an expression: what is wrong and where (1-based character, when known).
#[derive(Debug, Clone, PartialEq)]
pub struct ExprError {
    /// Position of the fault (1-based character), when it could be located.
    pub position: Option<usize>,
    /// What is wrong.
    pub message: String,
}

impl std::fmt::Display for ExprError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.position {
            Some(p) => write!(f, "at character {p}: {}", self.message),
            None => write!(f, "{}", self.message),
        }
    }
}

/// A parsed expression with its evaluation context.
pub struct Expression {
    node: Node<DefaultNumericTypes>,
    context: HashMapContext<DefaultNumericTypes>,
}

impl std::fmt::Debug for Expression {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Expression({})", self.node)
    }
}

fn number(v: &Value<DefaultNumericTypes>) -> evalexpr::EvalexprResult<f64, DefaultNumericTypes> {
    v.as_number()
}

/// The evaluation context: functions, `pi`, the constants and the variables (set to 0).
fn context(
    constants: &BTreeMap<String, f64>,
    variables: &[&str],
) -> HashMapContext<DefaultNumericTypes> {
    let mut c = HashMapContext::<DefaultNumericTypes>::new();
    for (name, f) in UNARY {
        let fun = Function::new(move |a: &Value<DefaultNumericTypes>| {
            Ok(Value::from_float(f(number(a)?)))
        });
        c.set_function(name.into(), fun)
            .expect("a fresh context takes functions");
    }
    for (name, f) in BINARY {
        let fun = Function::new(move |a: &Value<DefaultNumericTypes>| {
            let t = a.as_fixed_len_tuple(2)?;
            Ok(Value::from_float(f(number(&t[0])?, number(&t[1])?)))
        });
        c.set_function(name.into(), fun)
            .expect("a fresh context takes functions");
    }
    let values = std::iter::once(("pi".to_string(), std::f64::consts::PI))
        .chain(constants.iter().map(|(k, v)| (k.clone(), *v)))
        .chain(variables.iter().map(|v| (v.to_string(), 0.0)));
    for (name, v) in values {
        c.set_value(name, Value::from_float(v))
            .expect("a fresh context takes values");
    }
    c
}

/// The text with every integer literal written as a real (`2` -> `2.0`), so that division
/// is real division.
fn reals(text: &str) -> String {
    let chars: Vec<char> = text.chars().collect();
    let mut out = String::with_capacity(text.len() + 8);
    let mut k = 0;
    while k < chars.len() {
        let c = chars[k];
        let in_name = k > 0 && (chars[k - 1].is_alphanumeric() || chars[k - 1] == '_');
        if (c.is_ascii_digit() || c == '.') && !in_name {
            let start = k;
            k = operand_end(&chars, k);
            let literal: String = chars[start..k].iter().collect();
            out.push_str(&literal);
            if !literal.contains(['.', 'e', 'E']) {
                out.push_str(".0");
            }
            continue;
        }
        out.push(c);
        k += 1;
    }
    out
}

/// The end of the operand (number or name) starting at `k`.
fn operand_end(chars: &[char], mut k: usize) -> usize {
    if chars[k].is_ascii_digit() || chars[k] == '.' {
        while k < chars.len() && (chars[k].is_ascii_digit() || chars[k] == '.') {
            k += 1;
        }
        if k < chars.len() && (chars[k] == 'e' || chars[k] == 'E') {
            k += 1;
            if k < chars.len() && (chars[k] == '-' || chars[k] == '+') {
                k += 1;
            }
            while k < chars.len() && chars[k].is_ascii_digit() {
                k += 1;
            }
        }
        return k;
    }
    while k < chars.len() && (chars[k].is_alphanumeric() || chars[k] == '_' || chars[k] == ':') {
        k += 1;
    }
    k
}

/// Finds the position of a syntax fault by the tokens around it: two operands in a row (a
/// missing operator), an operator where an operand must come, an unbalanced parenthesis.
fn locate(text: &str) -> Option<(usize, String)> {
    #[derive(PartialEq, Clone, Copy)]
    enum Last {
        Start,
        Operand,
        Operator,
    }
    let chars: Vec<char> = text.chars().collect();
    let (mut last, mut depth, mut k) = (Last::Start, 0i64, 0);
    while k < chars.len() {
        let c = chars[k];
        let at = k + 1;
        if c.is_whitespace() {
            k += 1;
            continue;
        }
        if c.is_alphanumeric() || c == '_' || c == '.' {
            if last == Last::Operand {
                return Some((at, format!("an operator is missing before `{c}`")));
            }
            k = operand_end(&chars, k);
            // A name followed by `(` is a function call: the call's parenthesis follows.
            last = Last::Operand;
            if chars[k..].iter().find(|c| !c.is_whitespace()) == Some(&'(') {
                last = Last::Operator;
            }
            continue;
        }
        match c {
            '(' => {
                if last == Last::Operand {
                    return Some((at, "an operator is missing before `(`".into()));
                }
                depth += 1;
                last = Last::Start;
            }
            ')' => {
                if depth == 0 {
                    return Some((at, "`)` without a matching `(`".into()));
                }
                if last != Last::Operand && last != Last::Start {
                    return Some((at, "an operand is missing before `)`".into()));
                }
                depth -= 1;
                last = Last::Operand;
            }
            '-' | '+' | '!' if last != Last::Operand => last = Last::Operator,
            _ => {
                if last != Last::Operand {
                    return Some((at, format!("an operand is missing before `{c}`")));
                }
                last = Last::Operator;
            }
        }
        k += 1;
    }
    if depth > 0 {
        return Some((chars.len(), "a `(` is not closed".into()));
    }
    if last == Last::Operator {
        return Some((chars.len(), "the expression ends with an operator".into()));
    }
    None
}

/// The position (1-based character) of the whole word `name` in `text`.
fn position_of(text: &str, name: &str) -> Option<usize> {
    let chars: Vec<char> = text.chars().collect();
    let word: Vec<char> = name.chars().collect();
    let is_name = |c: char| c.is_alphanumeric() || c == '_';
    (0..chars.len())
        .find(|&k| {
            chars[k..].starts_with(&word)
                && (k == 0 || !is_name(chars[k - 1]))
                && chars.get(k + word.len()).is_none_or(|c| !is_name(*c))
        })
        .map(|k| k + 1)
}

impl Expression {
    /// Parses `text`, in the variables `variables` and the named `constants`, and checks that
    /// it evaluates to a number.
    pub fn parse(
        text: &str,
        variables: &[&str],
        constants: &BTreeMap<String, f64>,
    ) -> Result<Expression, ExprError> {
        if let Some((position, message)) = locate(text) {
            return Err(ExprError {
                position: Some(position),
                message,
            });
        }
        let node =
            build_operator_tree::<DefaultNumericTypes>(&reals(text)).map_err(|e| ExprError {
                position: None,
                message: e.to_string(),
            })?;
        let e = Expression {
            node,
            context: context(constants, variables),
        };
        // Evaluate once: unknown names and non-numbers show here.
        e.node.eval_with_context(&e.context).map_err(|err| {
            let message = err.to_string();
            let name = message.split('"').nth(1).map(str::to_string);
            ExprError {
                position: name.and_then(|n| position_of(text, &n)),
                message,
            }
        })?;
        e.eval(&[])?;
        Ok(e)
    }

    /// The value with the variables set as given (others stay 0).
    pub fn eval(&self, values: &[(&str, f64)]) -> Result<f64, ExprError> {
        let mut c = self.context.clone();
        for (name, v) in values {
            c.set_value(name.to_string(), Value::from_float(*v))
                .expect("variables are set in a context that has them");
        }
        let bad = |message: String| ExprError {
            position: None,
            message,
        };
        let v = self
            .node
            .eval_with_context(&c)
            .map_err(|e| bad(e.to_string()))?;
        match v {
            Value::Float(f) => Ok(f),
            Value::Int(i) => Ok(i as f64),
            other => Err(bad(format!("evaluates to {other}, not a number"))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn value(text: &str, vars: &[(&str, f64)]) -> Result<f64, ExprError> {
        let mut consts = BTreeMap::new();
        consts.insert("omega".to_string(), 2.0);
        Expression::parse(text, &["x", "y", "z", "t"], &consts)?.eval(vars)
    }

    #[test]
    fn expressions_evaluate_with_variables_constants_and_functions() {
        assert_eq!(value("1/2", &[]).unwrap(), 0.5);
        assert_eq!(value("-omega * y", &[("y", 3.0)]).unwrap(), -6.0);
        assert_eq!(
            value("sqrt(x^2 + y^2)", &[("x", 3.0), ("y", 4.0)]).unwrap(),
            5.0
        );
        assert!((value("atan2(1, 1)", &[]).unwrap() - std::f64::consts::FRAC_PI_4).abs() < 1e-15);
        assert_eq!(value("1e-3 * x", &[("x", 2.0)]).unwrap(), 2e-3);
        assert_eq!(value("2.5e3", &[]).unwrap(), 2500.0);
        assert_eq!(value("pi", &[]).unwrap(), std::f64::consts::PI);
        assert_eq!(value("min(x, 1) + max(x, 1)", &[("x", 3.0)]).unwrap(), 4.0);
    }

    #[test]
    fn faults_are_located() {
        let at = |text: &str| value(text, &[]).unwrap_err().position;
        assert_eq!(at("x +* y"), Some(4));
        assert_eq!(at("2 x"), Some(3));
        assert_eq!(at("(x + 1"), Some(6));
        assert_eq!(at("x + 1)"), Some(6));
        assert_eq!(at("x + foo"), Some(5));
        assert_eq!(at("bar(x)"), Some(1));
        assert_eq!(at("x *"), Some(3));
        assert!(value("x > 1", &[]).is_err(), "a comparison is not a number");
    }
}
