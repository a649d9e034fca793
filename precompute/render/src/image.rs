//! Linear RGB images.

/// A linear RGB image, row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// `width × height` linear RGB values.
    pub data: Vec<[f32; 3]>,
}

impl Image {
    /// A black image.
    #[must_use]
    pub fn new(width: usize, height: usize) -> Image {
        Image {
            width,
            height,
            data: vec![[0.0; 3]; width * height],
        }
    }

    /// Pixel `(x, y)`.
    #[must_use]
    pub fn at(&self, x: usize, y: usize) -> [f32; 3] {
        self.data[y * self.width + x]
    }
}
