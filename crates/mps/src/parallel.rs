//! Parallel building blocks shared by the CSR builders (neighbour lists, the PPE matrix,
//! sparse products): joining per-chunk results into one array without a sequential copy.

use rayon::prelude::*;

/// Concatenates `parts` into one vector, copying the parts in parallel into their slots.
pub fn concat<T: Copy + Default + Send + Sync>(parts: &[Vec<T>]) -> Vec<T> {
    let mut out = Vec::new();
    concat_into(parts, &mut out);
    out
}

/// [`concat`] into `out`, reusing its memory (a buffer kept from step to step takes no new
/// pages once it has grown: docs/decisions.md, "Reused PPE buffers").
pub fn concat_into<T: Copy + Default + Send + Sync>(parts: &[Vec<T>], out: &mut Vec<T>) {
    let total: usize = parts.iter().map(Vec::len).sum();
    out.clear();
    out.resize(total, T::default());
    let mut slots: Vec<&mut [T]> = Vec::with_capacity(parts.len());
    let mut rest = out.as_mut_slice();
    for p in parts {
        let (head, tail) = rest.split_at_mut(p.len());
        slots.push(head);
        rest = tail;
    }
    slots
        .into_par_iter()
        .zip(parts.par_iter())
        .for_each(|(s, p)| s.copy_from_slice(p));
}

/// CSR row offsets (`0, l0, l0 + l1, ...`) from per-chunk row lengths.
pub fn offsets(lengths: &[Vec<u32>]) -> Vec<u32> {
    let mut out = Vec::new();
    offsets_into(lengths, &mut out);
    out
}

/// [`offsets`] into `out`, reusing its memory.
pub fn offsets_into(lengths: &[Vec<u32>], out: &mut Vec<u32>) {
    out.clear();
    let mut acc = 0u32;
    out.push(0);
    for l in lengths.iter().flatten() {
        acc += l;
        out.push(acc);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn concat_and_offsets_join_chunks_in_order() {
        let parts = vec![vec![1u32, 2], vec![], vec![3, 4, 5]];
        assert_eq!(concat(&parts), vec![1, 2, 3, 4, 5]);
        assert_eq!(offsets(&[vec![2, 0], vec![3]]), vec![0, 2, 2, 5]);
    }
}
