//! `Vec2`: one value per axis, the mirror of WGSL's `vec2<Real>`.
//!
//! The shader holds every per-axis quantity in a `vec2` so that no array is
//! ever indexed by a run-time axis number (GPU compilers put such arrays in
//! slow local memory). The CPU mirror uses the same shape, component-wise
//! arithmetic in the same order, and the same two reductions ([`dot`] and
//! [`Vec2::max_element`]), so both compute the same numbers.

use super::Real;
use std::ops::{Add, Div, Index, IndexMut, Mul, Neg, Sub};

/// An (x, y) pair of per-axis values.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Vec2 {
    pub x: Real,
    pub y: Real,
}

impl Vec2 {
    pub const ZERO: Vec2 = Vec2 { x: 0.0, y: 0.0 };

    pub const fn new(x: Real, y: Real) -> Vec2 {
        Vec2 { x, y }
    }

    /// The same value on both axes.
    pub const fn splat(v: Real) -> Vec2 {
        Vec2 { x: v, y: v }
    }

    /// Applies `f` to each component.
    pub fn map(self, f: impl Fn(Real) -> Real) -> Vec2 {
        Vec2::new(f(self.x), f(self.y))
    }

    /// Component-wise `f(self, other)`.
    pub fn zip(self, other: Vec2, f: impl Fn(Real, Real) -> Real) -> Vec2 {
        Vec2::new(f(self.x, other.x), f(self.y, other.y))
    }

    pub fn abs(self) -> Vec2 {
        self.map(Real::abs)
    }

    /// The larger component.
    pub fn max_element(self) -> Real {
        self.x.max(self.y)
    }

    /// `select(no, yes, mask)` per component, as WGSL's `select`.
    pub fn select(no: Vec2, yes: Vec2, mask: [bool; 2]) -> Vec2 {
        Vec2::new(
            if mask[0] { yes.x } else { no.x },
            if mask[1] { yes.y } else { no.y },
        )
    }

    /// The components as an array, x first.
    pub fn to_array(self) -> [Real; 2] {
        [self.x, self.y]
    }
}

/// x a.x + y b.y, in that order (WGSL `dot` of a `vec2`).
pub fn dot(a: Vec2, b: Vec2) -> Real {
    a.x * b.x + a.y * b.y
}

/// |v|^2.
pub fn norm2(v: Vec2) -> Real {
    dot(v, v)
}

impl Index<usize> for Vec2 {
    type Output = Real;
    fn index(&self, i: usize) -> &Real {
        match i {
            0 => &self.x,
            1 => &self.y,
            _ => panic!("axis {i} of a Vec2"),
        }
    }
}

impl IndexMut<usize> for Vec2 {
    fn index_mut(&mut self, i: usize) -> &mut Real {
        match i {
            0 => &mut self.x,
            1 => &mut self.y,
            _ => panic!("axis {i} of a Vec2"),
        }
    }
}

impl Add for Vec2 {
    type Output = Vec2;
    fn add(self, o: Vec2) -> Vec2 {
        self.zip(o, |a, b| a + b)
    }
}

impl Sub for Vec2 {
    type Output = Vec2;
    fn sub(self, o: Vec2) -> Vec2 {
        self.zip(o, |a, b| a - b)
    }
}

impl Mul for Vec2 {
    type Output = Vec2;
    fn mul(self, o: Vec2) -> Vec2 {
        self.zip(o, |a, b| a * b)
    }
}

impl Div for Vec2 {
    type Output = Vec2;
    fn div(self, o: Vec2) -> Vec2 {
        self.zip(o, |a, b| a / b)
    }
}

impl Mul<Real> for Vec2 {
    type Output = Vec2;
    fn mul(self, s: Real) -> Vec2 {
        self.map(|a| a * s)
    }
}

impl Mul<Vec2> for Real {
    type Output = Vec2;
    fn mul(self, v: Vec2) -> Vec2 {
        v.map(|a| self * a)
    }
}

impl Add<Real> for Vec2 {
    type Output = Vec2;
    fn add(self, s: Real) -> Vec2 {
        self.map(|a| a + s)
    }
}

impl Sub<Real> for Vec2 {
    type Output = Vec2;
    fn sub(self, s: Real) -> Vec2 {
        self.map(|a| a - s)
    }
}

impl Sub<Vec2> for Real {
    type Output = Vec2;
    fn sub(self, v: Vec2) -> Vec2 {
        v.map(|a| self - a)
    }
}

impl Neg for Vec2 {
    type Output = Vec2;
    fn neg(self) -> Vec2 {
        self.map(|a| -a)
    }
}
