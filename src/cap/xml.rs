//! Writing XML text: escaping and the time format CAP 1.2 requires.

use chrono::{DateTime, Utc};

/// `text` with `&`, `<`, `>`, `"` and `'` escaped, for element content and attribute values.
pub fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for ch in text.chars() {
        match ch {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            // Characters XML 1.0 cannot hold at all (C0 controls other than tab, LF, CR).
            c if (c as u32) < 0x20 && !matches!(c, '\t' | '\n' | '\r') => out.push(' '),
            c => out.push(c),
        }
    }
    out
}

/// A CAP 1.2 date-time: `YYYY-MM-DDThh:mm:ss+00:00` (the schema's pattern refuses `Z` and
/// fractions of a second).
pub fn cap_time(t: DateTime<Utc>) -> String {
    t.format("%Y-%m-%dT%H:%M:%S+00:00").to_string()
}

/// An Atom (RFC 3339) date-time in UTC, to the second.
pub fn atom_time(t: DateTime<Utc>) -> String {
    t.format("%Y-%m-%dT%H:%M:%SZ").to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn markup_and_control_characters_do_not_survive() {
        assert_eq!(
            escape("<script>alert('x') & \"y\"</script>\u{1}"),
            "&lt;script&gt;alert(&apos;x&apos;) &amp; &quot;y&quot;&lt;/script&gt; "
        );
    }

    #[test]
    fn cap_times_carry_an_explicit_offset() {
        let t = DateTime::parse_from_rfc3339("2026-11-25T01:02:03.456Z")
            .unwrap()
            .with_timezone(&Utc);
        assert_eq!(cap_time(t), "2026-11-25T01:02:03+00:00");
        assert_eq!(atom_time(t), "2026-11-25T01:02:03Z");
    }
}
