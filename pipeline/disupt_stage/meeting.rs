//! Two values made on two threads, brought together by whichever thread comes second,
//! without either waiting for the other: the work on both goes on at once where the
//! second one is, while the first thread takes other work (a rayon join's other half).

use std::sync::Mutex;

/// The meeting place of an `A` and a `B` (each given once).
pub(super) struct Meeting<A, B> {
    slot: Mutex<(Option<A>, Option<B>)>,
}

impl<A, B> Meeting<A, B> {
    /// Neither has come yet.
    pub(super) fn new() -> Self {
        Self {
            slot: Mutex::new((None, None)),
        }
    }

    /// Leaves `a`: both, if `b` was already there (this thread then goes on with them),
    /// else none (the thread that brings `b` will).
    pub(super) fn bring_a(&self, a: A) -> Option<(A, B)> {
        let mut slot = self.slot.lock().unwrap_or_else(|e| e.into_inner());
        match slot.1.take() {
            Some(b) => Some((a, b)),
            None => {
                slot.0 = Some(a);
                None
            }
        }
    }

    /// Leaves `b`: both, if `a` was already there, else none.
    pub(super) fn bring_b(&self, b: B) -> Option<(A, B)> {
        let mut slot = self.slot.lock().unwrap_or_else(|e| e.into_inner());
        match slot.0.take() {
            Some(a) => Some((a, b)),
            None => {
                slot.1 = Some(b);
                None
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_second_to_come_takes_both_whichever_it_is() {
        let m = Meeting::new();
        assert_eq!(m.bring_a(1), None);
        assert_eq!(m.bring_b("b"), Some((1, "b")));

        let m = Meeting::new();
        assert_eq!(m.bring_b("b"), None);
        assert_eq!(m.bring_a(2), Some((2, "b")));
    }

    #[test]
    fn on_two_threads_exactly_one_of_them_meets() {
        for _ in 0..200 {
            let m = Meeting::new();
            let (a, b) = rayon::join(|| m.bring_a(7u8), || m.bring_b(9u16));
            match (a, b) {
                (Some(both), None) | (None, Some(both)) => assert_eq!(both, (7, 9)),
                other => panic!("met {other:?}"),
            }
        }
    }
}
