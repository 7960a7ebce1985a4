//! Flat ranges of instances as hyperslabs: a run of row-major flat
//! indices split into rectangular blocks of an N-D map ([`flat_to_blocks`])
//! and written block by block.

use anyhow::{Context, Result};
use hdf5::{Dataset, H5Type, Hyperslab, SliceOrIndex};
use ndarray::ArrayView;

/// Writes a run of row-major flat indices into an N-D dataset as a sequence
/// of hyperslabs.
pub(super) fn write_flat<T: H5Type>(
    ds: &Dataset,
    shape: &[usize],
    start: u64,
    data: &[T],
) -> Result<()> {
    if shape.is_empty() {
        if let Some(value) = data.first() {
            ds.write_scalar(value)?;
        }
        return Ok(());
    }
    let mut offset = 0;
    for block in flat_to_blocks(shape, start as usize, start as usize + data.len()) {
        let count: usize = block.iter().map(|&(_, n)| n).product();
        let dims: Vec<usize> = block.iter().map(|&(_, n)| n).collect();
        let view = ArrayView::from_shape(dims, &data[offset..offset + count])
            .context("internal: block shape does not match its data")?;
        let slab: Vec<SliceOrIndex> = block
            .iter()
            .map(|&(s, n)| SliceOrIndex::SliceCount {
                start: s,
                step: 1,
                count: n,
                block: 1,
            })
            .collect();
        ds.write_slice(view, Hyperslab::from(slab))?;
        offset += count;
    }
    Ok(())
}

/// Splits the row-major flat range [a, b) of an array of `shape` into
/// rectangular blocks, each given as (start, count) per dimension, in order.
pub fn flat_to_blocks(shape: &[usize], a: usize, b: usize) -> Vec<Vec<(usize, usize)>> {
    let mut out = Vec::new();
    blocks_rec(shape, a, b, &mut Vec::new(), &mut out);
    out
}

fn blocks_rec(
    shape: &[usize],
    a: usize,
    b: usize,
    prefix: &mut Vec<(usize, usize)>,
    out: &mut Vec<Vec<(usize, usize)>>,
) {
    if a >= b {
        return;
    }
    let inner: usize = shape[1..].iter().product();
    let (first, a_rem) = (a / inner, a % inner);
    let (last, b_rem) = (b / inner, b % inner);
    let full_block = |prefix: &Vec<(usize, usize)>, start: usize, count: usize| {
        let mut block = prefix.clone();
        block.push((start, count));
        block.extend(shape[1..].iter().map(|&n| (0, n)));
        block
    };
    if first == last {
        // Within one slice of the leading dimension.
        prefix.push((first, 1));
        blocks_rec(&shape[1..], a_rem, b_rem, prefix, out);
        prefix.pop();
        return;
    }
    let mut lead = first;
    if a_rem != 0 {
        prefix.push((first, 1));
        blocks_rec(&shape[1..], a_rem, inner, prefix, out);
        prefix.pop();
        lead += 1;
    }
    if last > lead {
        out.push(full_block(prefix, lead, last - lead));
    }
    if b_rem != 0 {
        prefix.push((last, 1));
        blocks_rec(&shape[1..], 0, b_rem, prefix, out);
        prefix.pop();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flatten(shape: &[usize], blocks: &[Vec<(usize, usize)>]) -> Vec<usize> {
        let mut out = Vec::new();
        for block in blocks {
            let mut idx: Vec<usize> = block.iter().map(|&(s, _)| s).collect();
            loop {
                let mut flat = 0;
                for (d, &i) in idx.iter().enumerate() {
                    flat = flat * shape[d] + i;
                }
                out.push(flat);
                // Row-major increment within the block.
                let mut d = block.len();
                loop {
                    if d == 0 {
                        break;
                    }
                    d -= 1;
                    idx[d] += 1;
                    if idx[d] < block[d].0 + block[d].1 {
                        break;
                    }
                    idx[d] = block[d].0;
                    if d == 0 {
                        d = usize::MAX;
                        break;
                    }
                }
                if d == usize::MAX || block.iter().all(|&(_, n)| n == 0) {
                    break;
                }
            }
        }
        out
    }

    #[test]
    fn blocks_cover_every_flat_range_in_order() {
        for shape in [vec![7], vec![3, 4], vec![2, 3, 5], vec![4, 1, 3]] {
            let n: usize = shape.iter().product();
            for a in 0..n {
                for b in a..=n {
                    let blocks = flat_to_blocks(&shape, a, b);
                    let got = flatten(&shape, &blocks);
                    let want: Vec<usize> = (a..b).collect();
                    assert_eq!(got, want, "shape {shape:?} range {a}..{b}: {blocks:?}");
                }
            }
        }
    }
}
