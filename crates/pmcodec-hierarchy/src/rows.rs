//! Compressed rows (CSR): many short lists stored as one flat array and the offset of each
//! list in it, built by counting, a prefix sum, and a fill. Child lists, adjacency, degenerate
//! sets and triangle incidence are all this shape; one flat array instead of a `Vec` per row is
//! what keeps their builds and walks cache-friendly (thousands of small vectors made keyframe
//! loads a tenth slower, see `progressive::incidence`).

/// Rows `0..rows` as `(offsets, items)`: row `r` is `items[offsets[r]..offsets[r + 1]]`, its
/// items in the order `entries` yields them. `entries` is called twice (count, then fill) and
/// must yield the same `(row, item)` pairs both times; pairs whose row is out of range are
/// skipped.
pub fn compressed_rows<I>(rows: usize, entries: impl Fn() -> I) -> (Vec<u32>, Vec<u32>)
where
    I: Iterator<Item = (u32, u32)>,
{
    let (mut offsets, mut items, mut fill) = (Vec::new(), Vec::new(), Vec::new());
    compressed_rows_into(rows, entries, &mut offsets, &mut items, &mut fill);
    (offsets, items)
}

/// [`compressed_rows`] into existing vectors (`fill` is scratch), so that a structure rebuilt
/// every frame keeps its allocations.
pub fn compressed_rows_into<I>(rows: usize, entries: impl Fn() -> I, offsets: &mut Vec<u32>, items: &mut Vec<u32>, fill: &mut Vec<u32>)
where
    I: Iterator<Item = (u32, u32)>,
{
    offsets.clear();
    offsets.resize(rows + 1, 0);
    for (r, _) in entries() {
        if (r as usize) < rows {
            offsets[r as usize + 1] += 1;
        }
    }
    for i in 0..rows {
        offsets[i + 1] += offsets[i];
    }
    fill.clone_from(offsets);
    items.clear();
    items.resize(offsets[rows] as usize, 0);
    for (r, item) in entries() {
        if (r as usize) < rows {
            let at = &mut fill[r as usize];
            items[*at as usize] = item;
            *at += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_keep_the_order_entries_come_in() {
        let pairs = [(2u32, 10u32), (0, 11), (2, 12), (5, 13), (0, 14)];
        let (offsets, items) = compressed_rows(3, || pairs.iter().copied());
        // Row 5 is out of range and skipped.
        assert_eq!(offsets, [0, 2, 2, 4]);
        assert_eq!(items, [11, 14, 10, 12]);
    }

    #[test]
    fn no_rows() {
        let (offsets, items) = compressed_rows(0, || [(0u32, 1u32)].into_iter());
        assert_eq!((offsets, items), (vec![0], vec![]));
    }
}
