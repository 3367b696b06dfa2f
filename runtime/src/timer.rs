//! GPU time of recorded work, for engines and benchmarks: timestamp queries written by two empty
//! compute passes that bracket what is recorded between [`GpuTimer::begin`] and
//! [`GpuTimer::end`] (the renderer records its own pass, so it cannot take `timestamp_writes`),
//! resolved into a buffer and read back after the submission. Needs
//! `wgpu::Features::TIMESTAMP_QUERY` on the device; [`GpuTimer::new`] is `None` without it.

/// Two timestamps and the buffers to read them back.
pub struct GpuTimer {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    read: wgpu::Buffer,
    /// Nanoseconds per timestamp tick.
    period: f64,
}

impl GpuTimer {
    /// A timer, or `None` when the device lacks `TIMESTAMP_QUERY`.
    pub fn new(device: &wgpu::Device, queue: &wgpu::Queue) -> Option<GpuTimer> {
        if !device.features().contains(wgpu::Features::TIMESTAMP_QUERY) {
            return None;
        }
        let set = device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("vdbcook timer"),
            ty: wgpu::QueryType::Timestamp,
            count: 2,
        });
        let buffer = |usage| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("vdbcook timer"),
                size: 16,
                usage,
                mapped_at_creation: false,
            })
        };
        Some(GpuTimer {
            set,
            resolve: buffer(wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC),
            read: buffer(wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST),
            period: queue.get_timestamp_period() as f64,
        })
    }

    fn stamp(&self, encoder: &mut wgpu::CommandEncoder, begin: bool) {
        let _ = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("vdbcook timestamp"),
            timestamp_writes: Some(wgpu::ComputePassTimestampWrites {
                query_set: &self.set,
                beginning_of_pass_write_index: begin.then_some(0),
                end_of_pass_write_index: (!begin).then_some(1),
            }),
        });
    }

    /// Records the start timestamp.
    pub fn begin(&self, encoder: &mut wgpu::CommandEncoder) {
        self.stamp(encoder, true);
    }

    /// Records the end timestamp and the copy that [`GpuTimer::read_ms`] reads.
    pub fn end(&self, encoder: &mut wgpu::CommandEncoder) {
        self.stamp(encoder, false);
        encoder.resolve_query_set(&self.set, 0..2, &self.resolve, 0);
        encoder.copy_buffer_to_buffer(&self.resolve, 0, &self.read, 0, 16);
    }

    /// After the submission holding `begin`..`end`: the GPU time between them, in ms (waits for
    /// the device). `None` if the read-back fails.
    pub fn read_ms(&self, device: &wgpu::Device) -> Option<f64> {
        let slice = self.read.slice(..);
        slice.map_async(wgpu::MapMode::Read, |_| {});
        device.poll(wgpu::PollType::wait_indefinitely()).ok()?;
        let ticks: [u64; 2] = {
            let data = slice.get_mapped_range().ok()?;
            [0, 1].map(|i| u64::from_le_bytes(data[8 * i..8 * i + 8].try_into().expect("8 bytes")))
        };
        self.read.unmap();
        Some(ticks[1].wrapping_sub(ticks[0]) as f64 * self.period * 1e-6)
    }
}
