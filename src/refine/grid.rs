//! The finest grid of a refinement and its square cells: index math only.
//!
//! A point is `(i, j)`: `i` along the first (slow) grid axis, `j` along the
//! second (fast) one, in steps of the finest grid. The coarse grid is every
//! `2^levels`-th point; a cell of side `size` (a power of two) has its
//! lower corner on a multiple of `size`.

/// A point of the finest grid: (index along the slow axis, along the fast).
pub type Point = (usize, usize);

/// The finest grid: `n[0] x n[1]` points, row-major, the second axis
/// fastest (the scene's flat instance order).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FineGrid {
    /// Points along each axis.
    pub n: [usize; 2],
    /// Halvings from the coarse grid to this one.
    pub levels: u32,
}

impl FineGrid {
    /// The finest grid of a coarse grid of `coarse` points per axis (each at
    /// least 2) refined `levels` times: `(c - 1) * 2^levels + 1` points.
    pub fn new(coarse: [usize; 2], levels: u32) -> FineGrid {
        FineGrid {
            n: coarse.map(|c| (c - 1) * (1usize << levels) + 1),
            levels,
        }
    }

    /// Points in the grid.
    pub fn len(&self) -> usize {
        self.n[0] * self.n[1]
    }

    /// Whether the grid has no points (never, for a valid scene).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The side of a coarse cell, in finest steps.
    pub fn coarse_size(&self) -> usize {
        1 << self.levels
    }

    /// The flat (row-major) index of a point.
    pub fn index(&self, p: Point) -> usize {
        p.0 * self.n[1] + p.1
    }

    /// The point of a flat index.
    pub fn point(&self, index: usize) -> Point {
        (index / self.n[1], index % self.n[1])
    }

    /// The cells of the coarse grid, row-major.
    pub fn coarse_cells(&self) -> Vec<Cell> {
        let size = self.coarse_size();
        let mut cells = Vec::new();
        for i in (0..self.n[0] - 1).step_by(size) {
            for j in (0..self.n[1] - 1).step_by(size) {
                cells.push(Cell { i, j, size });
            }
        }
        cells
    }

    /// Whether a cell lies within the grid.
    pub fn holds(&self, cell: &Cell) -> bool {
        cell.i + cell.size < self.n[0] && cell.j + cell.size < self.n[1]
    }
}

/// A square cell of the finest grid: lower corner `(i, j)`, side `size`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Cell {
    pub i: usize,
    pub j: usize,
    pub size: usize,
}

impl Cell {
    /// The corners: (i, j), (i, j + s), (i + s, j), (i + s, j + s).
    pub fn corners(&self) -> [Point; 4] {
        let s = self.size;
        [
            (self.i, self.j),
            (self.i, self.j + s),
            (self.i + s, self.j),
            (self.i + s, self.j + s),
        ]
    }

    /// The centre (the size is even).
    pub fn centre(&self) -> Point {
        let h = self.size / 2;
        (self.i + h, self.j + h)
    }

    /// The midpoints of the four edges.
    pub fn edge_midpoints(&self) -> [Point; 4] {
        let (s, h) = (self.size, self.size / 2);
        [
            (self.i, self.j + h),
            (self.i + s, self.j + h),
            (self.i + h, self.j),
            (self.i + h, self.j + s),
        ]
    }

    /// The four children of half the side.
    pub fn children(&self) -> [Cell; 4] {
        let h = self.size / 2;
        [(0, 0), (0, h), (h, 0), (h, h)].map(|(a, b)| Cell {
            i: self.i + a,
            j: self.j + b,
            size: h,
        })
    }

    /// The cells of the same size beside this one (edges and corners),
    /// whether or not they lie in a grid.
    pub fn neighbours(&self) -> Vec<Cell> {
        let s = self.size as isize;
        let mut out = Vec::with_capacity(8);
        for di in [-s, 0, s] {
            for dj in [-s, 0, s] {
                let (i, j) = (self.i as isize + di, self.j as isize + dj);
                if (di, dj) != (0, 0) && i >= 0 && j >= 0 {
                    out.push(Cell {
                        i: i as usize,
                        j: j as usize,
                        size: self.size,
                    });
                }
            }
        }
        out
    }

    /// Where a point of the closed cell lies in it: (u, v) in [0, 1]^2.
    pub fn local(&self, p: Point) -> (f64, f64) {
        let s = self.size as f64;
        ((p.0 - self.i) as f64 / s, (p.1 - self.j) as f64 / s)
    }

    /// Every point of the closed cell, row-major.
    pub fn points(&self) -> impl Iterator<Item = Point> + '_ {
        (self.i..=self.i + self.size)
            .flat_map(move |i| (self.j..=self.j + self.size).map(move |j| (i, j)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_finest_grid_holds_the_coarse_one_every_2_to_the_levels() {
        let g = FineGrid::new([17, 5], 4);
        assert_eq!(g.n, [257, 65]);
        assert_eq!(g.coarse_cells().len(), 16 * 4);
        for k in [0, 1, 64, 65, 257 * 65 - 1] {
            assert_eq!(g.index(g.point(k)), k);
        }
        let c = Cell {
            i: 16,
            j: 32,
            size: 16,
        };
        assert_eq!(c.centre(), (24, 40));
        assert!(g.holds(&c));
        assert!(!g.holds(&Cell {
            i: 16,
            j: 64,
            size: 16
        }));
        let kids = c.children();
        assert!(kids.iter().all(|k| k.size == 8));
        // The children's corners are the parent's corners, centre and edge
        // midpoints.
        let mut corners: Vec<Point> = kids.iter().flat_map(|k| k.corners()).collect();
        corners.sort();
        corners.dedup();
        let mut want: Vec<Point> = c.corners().to_vec();
        want.push(c.centre());
        want.extend(c.edge_midpoints());
        want.sort();
        assert_eq!(corners, want);
        assert_eq!(c.points().count(), 17 * 17);
        assert_eq!(c.local((20, 48)), (0.25, 1.0));
        assert_eq!(
            Cell {
                i: 0,
                j: 0,
                size: 2
            }
            .neighbours()
            .len(),
            3
        );
    }
}
