//! A plain row-major image, top row first, used for every CPU-side picture:
//! linear RGB radiance and intensity images (`Image<Vec3>`), masks
//! (`Image<bool>`) and per-pixel auxiliary data.

use glam::Vec3;

/// A `width x height` grid of pixels, row-major, top row first.
#[derive(Clone, Debug, PartialEq)]
pub struct Image<T> {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height` pixels; pixel `(x, y)` is at `y * width + x`.
    pub data: Vec<T>,
}

/// A linear RGB image (radiance, intensity or reflectance).
pub type RgbImage = Image<Vec3>;

impl<T: Clone> Image<T> {
    /// An image filled with `value`.
    pub fn new(width: u32, height: u32, value: T) -> Self {
        Self {
            width,
            height,
            data: vec![value; width as usize * height as usize],
        }
    }
}

impl<T> Image<T> {
    /// An image with pixel `(x, y)` set to `f(x, y)`.
    pub fn from_fn(width: u32, height: u32, mut f: impl FnMut(u32, u32) -> T) -> Self {
        let mut data = Vec::with_capacity(width as usize * height as usize);
        for y in 0..height {
            for x in 0..width {
                data.push(f(x, y));
            }
        }
        Self {
            width,
            height,
            data,
        }
    }

    /// The pixel at `(x, y)`, or `None` outside the image.
    pub fn get(&self, x: u32, y: u32) -> Option<&T> {
        (x < self.width && y < self.height).then(|| &self.data[self.index(x, y)])
    }

    /// The pixel at `(x, y)` for writing, or `None` outside the image.
    pub fn get_mut(&mut self, x: u32, y: u32) -> Option<&mut T> {
        let i = self.index(x, y);
        (x < self.width && y < self.height).then(|| &mut self.data[i])
    }

    /// A new image of `f` applied to every pixel.
    pub fn map<U>(&self, f: impl FnMut(&T) -> U) -> Image<U> {
        Image {
            width: self.width,
            height: self.height,
            data: self.data.iter().map(f).collect(),
        }
    }

    /// True when both images have the same size.
    pub fn same_size<U>(&self, other: &Image<U>) -> bool {
        self.width == other.width && self.height == other.height
    }

    fn index(&self, x: u32, y: u32) -> usize {
        y as usize * self.width as usize + x as usize
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn row_major_indexing() {
        let img = Image::from_fn(3, 2, |x, y| x + 10 * y);
        assert_eq!(img.data, vec![0, 1, 2, 10, 11, 12]);
        assert_eq!(img.get(2, 1), Some(&12));
        assert_eq!(img.get(3, 0), None);
        assert_eq!(img.get(0, 2), None);
        let mut m = img.map(|v| *v as f32);
        *m.get_mut(1, 1).unwrap() = -1.0;
        assert_eq!(m.data[4], -1.0);
        assert!(m.get_mut(5, 5).is_none());
        assert!(Image::new(0, 5, Vec3::ONE).data.is_empty());
    }
}
