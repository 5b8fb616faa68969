//! The value of a given rank among many `u64`s, without a copy of them: a radix select
//! that reads them four times, 16 bits at a time, from the top (a histogram of 65 536
//! counts each time). What a sort of a copy would put at that rank, in O(n) time and O(1)
//! room: a 12-hour run's 4.32 M sample intervals took a 34.56-MB copy before.

/// Bits read per pass.
const DIGIT_BITS: u32 = 16;

/// The value at `rank` (0 is the smallest) of those `values()` yields, the same each time
/// it is called; `None` when there are no more than `rank` of them.
pub fn nth_smallest<I: Iterator<Item = u64>>(values: impl Fn() -> I, rank: usize) -> Option<u64> {
    let mut counts = vec![0usize; 1 << DIGIT_BITS];
    // The bits above `shift` found so far (`prefix`), and the rank within the values that
    // have them.
    let (mut prefix, mut rank) = (0u64, rank);
    for pass in 0..(u64::BITS / DIGIT_BITS) {
        let shift = u64::BITS - DIGIT_BITS * (pass + 1);
        let above = |v: u64| {
            if pass == 0 {
                0
            } else {
                v >> (shift + DIGIT_BITS)
            }
        };
        counts.fill(0);
        for v in values().filter(|&v| above(v) == prefix) {
            counts[((v >> shift) & 0xFFFF) as usize] += 1;
        }
        let mut digit = None;
        for (d, &c) in counts.iter().enumerate() {
            if rank < c {
                digit = Some(d as u64);
                break;
            }
            rank -= c;
        }
        prefix = (prefix << DIGIT_BITS) | digit?;
    }
    Some(prefix)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every rank of awkward sets (ties, extremes, wide and narrow spreads) is the sorted
    /// copy's; a rank past the end is none.
    #[test]
    fn every_rank_is_the_sorted_copys() {
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let sets: Vec<Vec<u64>> = vec![
            vec![],
            vec![7],
            vec![u64::MAX, 0, u64::MAX, 1 << 63],
            (0..500).map(|_| 10_000_000 + next() % 3).collect(),
            (0..500).map(|_| next()).collect(),
            (0..500).map(|_| next() >> 40).collect(),
            (0..500)
                .map(|k| if k % 7 == 0 { next() } else { 10_000_000 })
                .collect(),
        ];
        for set in &sets {
            let mut sorted = set.clone();
            sorted.sort_unstable();
            for (rank, &want) in sorted.iter().enumerate() {
                assert_eq!(nth_smallest(|| set.iter().copied(), rank), Some(want));
            }
            assert_eq!(nth_smallest(|| set.iter().copied(), set.len()), None);
        }
    }
}
