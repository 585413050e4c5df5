//! Point names in the order people expect: runs of digits compare by value, so T2 comes before
//! T10 and 9 before 10 (text order puts 10 first).

use std::cmp::Ordering;

/// Compares two names with their digit runs taken as numbers (then as text, for equal values
/// such as `07` and `7`).
pub fn natural_cmp(a: &str, b: &str) -> Ordering {
    let (mut x, mut y) = (a.as_bytes(), b.as_bytes());
    loop {
        match (x.first(), y.first()) {
            (None, None) => return a.cmp(b),
            (None, Some(_)) => return Ordering::Less,
            (Some(_), None) => return Ordering::Greater,
            (Some(c), Some(d)) if c.is_ascii_digit() && d.is_ascii_digit() => {
                let n = x.iter().take_while(|c| c.is_ascii_digit()).count();
                let m = y.iter().take_while(|c| c.is_ascii_digit()).count();
                let (p, q) = (trim_zeros(&x[..n]), trim_zeros(&y[..m]));
                let by_value = p.len().cmp(&q.len()).then_with(|| p.cmp(q));
                if by_value != Ordering::Equal {
                    return by_value;
                }
                (x, y) = (&x[n..], &y[m..]);
            }
            (Some(c), Some(d)) => {
                if c != d {
                    return c.cmp(d);
                }
                (x, y) = (&x[1..], &y[1..]);
            }
        }
    }
}

fn trim_zeros(digits: &[u8]) -> &[u8] {
    let k = digits.iter().take_while(|&&c| c == b'0').count();
    &digits[k..]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn digit_runs_compare_by_value() {
        let mut names = vec!["10", "2", "1", "T10", "T9", "T009b", "B", "T9a", "11"];
        names.sort_by(|a, b| natural_cmp(a, b));
        assert_eq!(
            names,
            ["1", "2", "10", "11", "B", "T9", "T9a", "T009b", "T10"]
        );
        assert_eq!(natural_cmp("07", "7"), "07".cmp("7"));
        assert_eq!(natural_cmp("P1", "P1"), Ordering::Equal);
    }
}
