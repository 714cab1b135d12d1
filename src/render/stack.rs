//! A fixed-capacity stack for tree traversals (the photon kd-tree, the BVH) that is not
//! zeroed on creation: zeroing the array once per query showed up in render profiles as
//! memset, 1 KiB for the kd-tree, 256 bytes a ray for the BVH (docs/performance-history.md,
//! "unzeroed traversal stack" and "unzeroed BVH stack").

use std::mem::MaybeUninit;

pub(crate) struct Stack<T: Copy, const N: usize> {
    items: [MaybeUninit<T>; N],
    len: usize,
}

impl<T: Copy, const N: usize> Stack<T, N> {
    #[inline]
    pub fn new() -> Self {
        Stack {
            items: [const { MaybeUninit::uninit() }; N],
            len: 0,
        }
    }

    /// Pushes `v`; on a full stack the value is dropped instead, as obvhs's own traversal
    /// stack does, so the BVH's hits are the ones obvhs would find. The kd-tree is balanced
    /// and never comes near its capacity; a BVH deeper than 32 levels would lose nodes with
    /// either stack (obvhs's validation asks for less).
    #[inline]
    pub fn push(&mut self, v: T) {
        self.items[self.len] = MaybeUninit::new(v);
        self.len = (self.len + 1).min(N - 1);
    }

    #[inline]
    pub fn pop(&mut self) -> Option<T> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: every slot below `len` was written by `push`.
        Some(unsafe { self.items[self.len].assume_init() })
    }

    #[inline]
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// [`Stack::pop`] on a stack known not to be empty (obvhs's `traverse!` checks first).
    #[inline]
    pub fn pop_fast(&mut self) -> T {
        self.pop().expect("pop_fast on an empty stack")
    }
}

#[cfg(test)]
mod tests {
    use super::Stack;

    #[test]
    fn pops_in_reverse_order_and_drops_what_overflows() {
        let mut s: Stack<u32, 4> = Stack::new();
        assert!(s.is_empty());
        for v in 1..=5 {
            s.push(v);
        }
        // Capacity 4 keeps three: the fourth and fifth pushes land in the spare slot.
        assert_eq!(
            (s.pop(), s.pop(), s.pop(), s.pop()),
            (Some(3), Some(2), Some(1), None)
        );
        s.push(7);
        assert_eq!(s.pop_fast(), 7);
        assert!(s.is_empty());
    }
}
