//! The rendered image: display colours (linear RGBA, f32) and one raw value per pixel (the
//! mode's quantity, for comparisons that must not go through a colour map).

/// A rendered image, row 0 at the top.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    /// `width × height × 4` display values (RGBA, linear, nominally in [0, 1]).
    pub rgba: Vec<f32>,
    /// `width × height` raw values: the mode's quantity (see the crate docs).
    pub value: Vec<f32>,
}

impl Image {
    /// 8-bit RGBA: each channel clamped to [0, 1], times 255, rounded (no transfer curve). A
    /// non-finite channel (never produced) would become 0.
    pub fn to_rgba8(&self) -> Vec<u8> {
        self.rgba
            .iter()
            .map(|&c| {
                if c.is_finite() {
                    (c.clamp(0.0, 1.0) * 255.0).round() as u8
                } else {
                    0
                }
            })
            .collect()
    }

    /// RGBA of pixel `(i, j)`.
    pub fn pixel(&self, i: u32, j: u32) -> [f32; 4] {
        let k = 4 * (j as usize * self.width as usize + i as usize);
        [
            self.rgba[k],
            self.rgba[k + 1],
            self.rgba[k + 2],
            self.rgba[k + 3],
        ]
    }

    /// Whether every channel and value is finite.
    pub fn all_finite(&self) -> bool {
        self.rgba.iter().chain(&self.value).all(|v| v.is_finite())
    }
}
