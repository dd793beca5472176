//! Byte-level mutation of a loader's input, shared by the loaders' fuzz tests.

/// `base` mutated as the byte-level loader fuzzers do: each `(at, value)` of `numbers`
/// replaces the run of digits starting at `at` (if any) by `value` written out, each
/// `(at, byte)` of `flips` overwrites one byte, and `cut` truncates the result when it is a
/// multiple of 3 (a third of the cases end early).
pub fn mutated(
    base: &[u8],
    cut: usize,
    flips: &[(usize, u8)],
    numbers: &[(usize, impl std::fmt::Display)],
) -> Vec<u8> {
    let mut bytes = base.to_vec();
    for (at, value) in numbers {
        let at = *at;
        let mut end = at;
        while end < bytes.len() && bytes[end].is_ascii_digit() {
            end += 1;
        }
        if end > at {
            bytes.splice(at..end, value.to_string().into_bytes());
        }
    }
    for &(at, value) in flips {
        if let Some(b) = bytes.get_mut(at) {
            *b = value;
        }
    }
    if cut.is_multiple_of(3) {
        bytes.truncate(cut);
    }
    bytes
}
