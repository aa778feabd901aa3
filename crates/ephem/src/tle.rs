//! Two-line element set text checks that do not need propagation.

/// The modulo-10 checksum of one TLE line (NORAD convention): the sum of all digits in
/// columns 1-68, with each minus sign counting as 1; letters, blanks, periods and plus
/// signs count as 0.
pub fn checksum(line: &str) -> u32 {
    line.chars()
        .take(68)
        .map(|c| match c {
            '0'..='9' => c.to_digit(10).unwrap_or(0),
            '-' => 1,
            _ => 0,
        })
        .sum::<u32>()
        % 10
}

/// True when column 69 holds the digit that [`checksum`] computes for columns 1-68.
pub fn checksum_ok(line: &str) -> bool {
    let stated = line.chars().nth(68).and_then(|c| c.to_digit(10));
    stated == Some(checksum(line))
}

#[cfg(test)]
mod tests {
    use super::*;

    // The RAX-2-like TLE of docs/rax2-scenario.md carries valid checksums.
    const L1: &str = "1 37853U 11061D   11308.77065972  .00000000  00000-0  20000-4 0  9997";
    const L2: &str = "2 37853 101.7000  50.0000 0300509 130.0000 230.0000 14.86144463  1000";

    #[test]
    fn valid_lines_pass() {
        assert!(checksum_ok(L1));
        assert!(checksum_ok(L2));
    }

    #[test]
    fn one_changed_digit_fails() {
        let bad = L1.replace("37853U", "37854U");
        assert!(!checksum_ok(&bad));
        assert!(
            !checksum_ok(&L2[..68]),
            "a line without column 69 has no checksum"
        );
    }
}
