//! Path segments of the service's own links.

/// A path segment percent-encoded (site and point names are user input): everything but ASCII
/// letters, digits and `-._~`.
pub fn seg(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for b in s.bytes() {
        if b.is_ascii_alphanumeric() || b"-._~".contains(&b) {
            out.push(b as char);
        } else {
            out.push_str(&format!("%{b:02X}"));
        }
    }
    out
}
