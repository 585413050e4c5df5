//! A user's value repeated in an error message is cut to [`MAX_ECHO_CHARS`] characters and an
//! ellipsis: an answer (or a log line) does not grow with what one request sent.

use std::borrow::Cow;

/// The most characters of a user's value an error message repeats.
pub const MAX_ECHO_CHARS: usize = 80;

/// `value` as an error message repeats it: whole when it has at most [`MAX_ECHO_CHARS`]
/// characters, else its first [`MAX_ECHO_CHARS`] characters followed by `…`.
pub fn truncate_for_message(value: &str) -> Cow<'_, str> {
    match value.char_indices().nth(MAX_ECHO_CHARS) {
        None => Cow::Borrowed(value),
        Some((end, _)) => Cow::Owned(format!("{}…", &value[..end])),
    }
}

/// `message` with every run quoted in double quotes or backticks (how serde's messages repeat a
/// value: `invalid type: string "…"`, ``unknown field `…` ``) cut by [`truncate_for_message`]; the
/// rest is left as it is. The last line of defence of the API's error answers, for messages
/// written by libraries; the service's own messages cut what they repeat themselves.
pub fn truncate_quoted(message: &str) -> Cow<'_, str> {
    if message.chars().count() <= MAX_ECHO_CHARS {
        return Cow::Borrowed(message);
    }
    let mut out = String::with_capacity(message.len().min(4 * MAX_ECHO_CHARS));
    let mut rest = message;
    let mut cut = false;
    while let Some(open) = rest.find(['"', '`']) {
        let quote = &rest[open..open + 1];
        out.push_str(&rest[..=open]);
        let after = &rest[open + 1..];
        let Some(close) = after.find(quote) else {
            // an unclosed quote runs to the end
            let shown = truncate_for_message(after);
            cut |= shown.len() != after.len();
            out.push_str(&shown);
            rest = "";
            break;
        };
        let inner = &after[..close];
        let shown = truncate_for_message(inner);
        cut |= shown.len() != inner.len();
        out.push_str(&shown);
        out.push_str(quote);
        rest = &after[close + 1..];
    }
    out.push_str(rest);
    if cut {
        Cow::Owned(out)
    } else {
        Cow::Borrowed(message)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_values_are_cut_to_80_characters_and_an_ellipsis() {
        assert_eq!(truncate_for_message("kamo"), "kamo");
        let exact = "x".repeat(80);
        assert_eq!(truncate_for_message(&exact), exact.as_str());
        let long = "é".repeat(10_000);
        let shown = truncate_for_message(&long);
        assert_eq!(shown.chars().count(), 81);
        assert!(shown.ends_with("é…"));
    }

    #[test]
    fn quoted_runs_are_cut_and_the_rest_kept() {
        let long = "a".repeat(500);
        let message = format!("images[0].id: invalid type: string \"{long}\", expected `{long}` x");
        let shown = truncate_quoted(&message);
        let cut = format!("{}…", "a".repeat(80));
        assert_eq!(
            shown,
            format!("images[0].id: invalid type: string \"{cut}\", expected `{cut}` x")
        );
        let plain = format!("the body is {} long; \"short\"", "long ".repeat(30));
        assert_eq!(truncate_quoted(&plain), plain.as_str());
        let open = format!("unterminated \"{long}");
        assert_eq!(truncate_quoted(&open), format!("unterminated \"{cut}"));
    }
}
