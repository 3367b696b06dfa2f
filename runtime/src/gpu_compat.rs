//! The one wgpu 29 / wgpu 30 difference in the runtime's calls, bridged without `cfg`: the
//! runtime builds against either line (features `wgpu30`, the default, and `wgpu29`; `lib.rs`
//! names the chosen one `wgpu`), so Bevy 0.20 (wgpu 30) and Bevy 0.19 (wgpu 29) can both link
//! it (`docs/decisions.md`).

/// `BufferSlice::get_mapped_range()` returns a `BufferView` in wgpu 29 (it panics on a bad
/// range) and `Result<BufferView, MapRangeError>` in wgpu 30: both as an `Option`.
pub trait MappedRange {
    /// The view, `None` where wgpu 30 returned an error.
    fn into_view(self) -> Option<wgpu::BufferView>;
}

impl MappedRange for wgpu::BufferView {
    fn into_view(self) -> Option<wgpu::BufferView> {
        Some(self)
    }
}

impl<E> MappedRange for Result<wgpu::BufferView, E> {
    fn into_view(self) -> Option<wgpu::BufferView> {
        self.ok()
    }
}

/// The mapped bytes of `slice` (after its `map_async` completed); `None` on wgpu 30's error.
pub fn mapped_range(slice: &wgpu::BufferSlice<'_>) -> Option<wgpu::BufferView> {
    slice.get_mapped_range().into_view()
}
