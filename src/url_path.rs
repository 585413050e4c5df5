//! Percent-encoding of URL path segments: one encoder for the service's own links (the HTTP
//! layer, the dashboard) and the links the webhooks send to receivers. It depends on nothing, so
//! every layer may use it without an import cycle.

/// A path segment percent-encoded (site, point and alert ids are user input): everything but
/// ASCII letters, digits and `-._~` (RFC 3986's unreserved characters) as `%XX` of its UTF-8
/// bytes.
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
