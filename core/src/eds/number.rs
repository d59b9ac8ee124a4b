//! Numbers as CiA 306 writes them: decimal, hexadecimal (`0x`), octal (a leading `0`), with an
//! optional sign, and the `$NODEID` expressions of node-relative values (`$NODEID+0x180`, also
//! `0x180+$NODEID` and `$NODEID` alone, any case, spaces anywhere).
//!
//! A number may be followed by a `;` comment (`DefaultValue=0x80 ; COB-ID`): the comment goes.

/// Why a number could not be read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum NumError {
    /// Nothing, or not a number.
    Bad,
    /// More than 64 bits.
    Overflow,
    /// A leading zero (octal) with the digit 8 or 9; holds the value read as decimal.
    OctalDigits(i128),
}

/// A literal's value (wide enough for every u64 and i64) and how it was written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Literal {
    pub value: i128,
    /// 10, 16 or 8.
    pub radix: u32,
    /// Written with a sign (`-5`, `+5`).
    pub signed: bool,
}

/// `text` without a trailing `;` comment.
pub(crate) fn strip_comment(text: &str) -> &str {
    match text.find(';') {
        Some(i) => text[..i].trim_end(),
        None => text,
    }
}

/// Reads one literal (no `$NODEID`).
pub(crate) fn literal(text: &str) -> Result<Literal, NumError> {
    let t = text.trim();
    let (neg, signed, t) = match t.as_bytes().first() {
        Some(b'-') => (true, true, t[1..].trim_start()),
        Some(b'+') => (false, true, t[1..].trim_start()),
        _ => (false, false, t),
    };
    let (radix, digits) = if let Some(h) = t.strip_prefix("0x").or(t.strip_prefix("0X")) {
        (16, h)
    } else if t.len() > 1 && t.starts_with('0') {
        (8, &t[1..])
    } else {
        (10, t)
    };
    if digits.is_empty() {
        return Err(NumError::Bad);
    }
    let value = match digits_value(digits, radix) {
        Ok(v) => v,
        Err(NumError::Bad) if radix == 8 && digits.bytes().all(|b| b.is_ascii_digit()) => {
            let v = digits_value(digits, 10)?;
            return Err(NumError::OctalDigits(if neg { -v } else { v }));
        }
        Err(e) => return Err(e),
    };
    let value = if neg { -value } else { value };
    if value < i64::MIN as i128 {
        return Err(NumError::Overflow);
    }
    Ok(Literal {
        value,
        radix,
        signed,
    })
}

fn digits_value(digits: &str, radix: u32) -> Result<i128, NumError> {
    let mut v: i128 = 0;
    for c in digits.chars() {
        let d = c.to_digit(radix).ok_or(NumError::Bad)?;
        v = v * radix as i128 + d as i128;
        if v > u64::MAX as i128 {
            return Err(NumError::Overflow);
        }
    }
    Ok(v)
}

/// A value that may be node-relative: `node_id` is true when `$NODEID` is a term, and
/// `literal` is the other term (zero when `$NODEID` stands alone).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Expr {
    pub node_id: bool,
    pub literal: Literal,
}

/// Reads a number or a `$NODEID` expression (comment stripped).
pub(crate) fn expr(text: &str) -> Result<Expr, NumError> {
    let t = strip_comment(text.trim());
    if !t.contains('$') {
        return literal(t).map(|literal| Expr {
            node_id: false,
            literal,
        });
    }
    let mut node_id = false;
    let mut lit: Option<Literal> = None;
    for term in t.split('+') {
        let term = term.trim();
        if term.eq_ignore_ascii_case("$NODEID") {
            if node_id {
                return Err(NumError::Bad);
            }
            node_id = true;
        } else {
            if lit.is_some() {
                return Err(NumError::Bad);
            }
            let l = literal(term)?;
            if l.value < 0 || l.signed {
                return Err(NumError::Bad);
            }
            lit = Some(l);
        }
    }
    if !node_id {
        return Err(NumError::Bad);
    }
    Ok(Expr {
        node_id,
        literal: lit.unwrap_or(Literal {
            value: 0,
            radix: 10,
            signed: false,
        }),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(t: &str) -> i128 {
        literal(t).unwrap().value
    }

    #[test]
    fn decimal_hex_and_octal() {
        assert_eq!(v("10"), 10);
        assert_eq!(v("0x10"), 16);
        assert_eq!(v("0X1f"), 31);
        assert_eq!(v("010"), 8);
        assert_eq!(v("0"), 0);
        assert_eq!(v("-5"), -5);
        assert_eq!(v(" +7 "), 7);
        assert_eq!(v("0xFFFFFFFFFFFFFFFF"), u64::MAX as i128);
        assert_eq!(v("-9223372036854775808"), i64::MIN as i128);
        assert_eq!(literal("0x1_0"), Err(NumError::Bad));
        assert_eq!(literal("0x"), Err(NumError::Bad));
        assert_eq!(literal(""), Err(NumError::Bad));
        assert_eq!(literal("-"), Err(NumError::Bad));
        assert_eq!(literal("0x10000000000000000"), Err(NumError::Overflow));
        assert_eq!(literal("-9223372036854775809"), Err(NumError::Overflow));
        assert_eq!(literal("018"), Err(NumError::OctalDigits(18)));
        assert_eq!(literal("0a"), Err(NumError::Bad));
    }

    #[test]
    fn node_id_expressions_either_way_round() {
        let e = |t| expr(t).unwrap();
        assert_eq!(
            (e("$NODEID+0x180").node_id, e("$NODEID+0x180").literal.value),
            (true, 0x180)
        );
        assert_eq!(e("0x180 + $nodeid").literal.value, 0x180);
        assert_eq!(e("$NodeId").literal.value, 0);
        assert!(!e("0x80 ; comment").node_id);
        assert_eq!(e("0x80 ; comment").literal.value, 0x80);
        assert_eq!(expr("$NODEID+$NODEID"), Err(NumError::Bad));
        assert_eq!(expr("$NODEID+1+2"), Err(NumError::Bad));
        assert_eq!(expr("$NODEID-1"), Err(NumError::Bad));
        assert_eq!(expr("$NODE+1"), Err(NumError::Bad));
    }
}
