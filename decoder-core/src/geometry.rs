//! Pixel geometry shared by every layer: rectangles of pixels and the quadtree's square nodes.

/// An axis-aligned rectangle of pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Rect {
    /// Left column.
    pub x: u32,
    /// Top row.
    pub y: u32,
    /// Width in pixels.
    pub w: u32,
    /// Height in pixels.
    pub h: u32,
}

impl Rect {
    /// The rectangle of the given size at the origin.
    pub const fn of_size(w: u32, h: u32) -> Self {
        Rect { x: 0, y: 0, w, h }
    }

    /// Everything (the largest rectangle at the origin).
    pub const EVERYTHING: Rect = Rect::of_size(u32::MAX, u32::MAX);

    /// One past the right column (wide enough not to overflow).
    pub fn right(&self) -> u64 {
        u64::from(self.x) + u64::from(self.w)
    }

    /// One past the bottom row (wide enough not to overflow).
    pub fn bottom(&self) -> u64 {
        u64::from(self.y) + u64::from(self.h)
    }

    /// Whether the rectangle holds no pixel.
    pub fn is_empty(&self) -> bool {
        self.w == 0 || self.h == 0
    }

    /// Whether pixel `(x, y)` lies inside this rectangle.
    pub fn contains_point(&self, x: u32, y: u32) -> bool {
        self.x <= x && u64::from(x) < self.right() && self.y <= y && u64::from(y) < self.bottom()
    }

    /// Whether `other` lies inside this rectangle.
    pub fn contains(&self, other: &Rect) -> bool {
        self.x <= other.x
            && self.y <= other.y
            && other.right() <= self.right()
            && other.bottom() <= self.bottom()
    }

    /// Whether the square of side `ext` at `(x, y)` overlaps this rectangle.
    pub fn overlaps_square(&self, x: u32, y: u32, ext: u32) -> bool {
        u64::from(x) < self.right()
            && u64::from(y) < self.bottom()
            && u64::from(x) + u64::from(ext) > u64::from(self.x)
            && u64::from(y) + u64::from(ext) > u64::from(self.y)
    }

    /// The pixels both rectangles hold (an empty rectangle at the origin when they are
    /// disjoint).
    pub fn intersect(&self, other: &Rect) -> Rect {
        let x0 = self.x.max(other.x);
        let y0 = self.y.max(other.y);
        // Offsets of the corner into each rectangle: 32-bit throughout, no sum can overflow.
        let (ax, bx) = (x0 - self.x, x0 - other.x);
        let (ay, by) = (y0 - self.y, y0 - other.y);
        if ax >= self.w || bx >= other.w || ay >= self.h || by >= other.h {
            return Rect::of_size(0, 0);
        }
        Rect {
            x: x0,
            y: y0,
            w: (self.w - ax).min(other.w - bx),
            h: (self.h - ay).min(other.h - by),
        }
    }
}

/// A quadtree node: the square of side `2^log2` pixels at `(x, y)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Node {
    /// Left column.
    pub x: u32,
    /// Top row.
    pub y: u32,
    /// Side, as a power of two.
    pub log2: u8,
}

impl Node {
    /// Side in pixels.
    pub fn size(&self) -> u32 {
        1 << self.log2
    }

    /// The node's square as a rectangle.
    pub fn rect(&self) -> Rect {
        Rect {
            x: self.x,
            y: self.y,
            w: self.size(),
            h: self.size(),
        }
    }

    /// The four children in coding (Z) order.
    pub fn children(&self) -> [Node; 4] {
        let h = self.size() / 2;
        let log2 = self.log2 - 1;
        let at = |dx: u32, dy: u32| Node {
            x: self.x + dx,
            y: self.y + dy,
            log2,
        };
        [at(0, 0), at(h, 0), at(0, h), at(h, h)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn intersection() {
        let a = Rect {
            x: 2,
            y: 3,
            w: 10,
            h: 10,
        };
        let b = Rect {
            x: 5,
            y: 0,
            w: 100,
            h: 5,
        };
        let both = Rect {
            x: 5,
            y: 3,
            w: 7,
            h: 2,
        };
        assert_eq!(a.intersect(&b), both);
        assert_eq!(a.intersect(&Rect::of_size(2, 100)), Rect::of_size(0, 0));
        let far = Rect {
            x: u32::MAX,
            y: u32::MAX,
            w: u32::MAX,
            h: u32::MAX,
        };
        assert_eq!(far.intersect(&a), Rect::of_size(0, 0));
        assert!(Rect::EVERYTHING.contains(&a));
    }
}
