//! GPU time of recorded work, for engines and benchmarks: timestamp queries written by two empty
//! compute passes that bracket what is recorded between [`GpuTimer::begin`] and
//! [`GpuTimer::end`] (the renderer records its own pass, so it cannot take `timestamp_writes`),
//! resolved into a buffer and read back after the submission. Needs
//! `wgpu::Features::TIMESTAMP_QUERY` on the device; [`GpuTimer::new`] is `None` without it.
//!
//! Two ways to read: an engine calls [`GpuTimer::request`] after submitting and
//! [`GpuTimer::try_read_ms`] on a later frame, which never blocks (the map completes when the
//! engine polls the device, as it does anyway); tools and benches call [`GpuTimer::read_ms`], which
//! waits.

use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::Arc;

/// `GpuTimer::state`: no read requested, mapping, mapped, failed.
const IDLE: u8 = 0;
const PENDING: u8 = 1;
const MAPPED: u8 = 2;
const FAILED: u8 = 3;

/// Two timestamps and the buffers to read them back.
pub struct GpuTimer {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    read: wgpu::Buffer,
    /// Nanoseconds per timestamp tick.
    period: f64,
    /// Where a non-blocking read stands (`IDLE`, `PENDING`, `MAPPED`, `FAILED`).
    state: Arc<AtomicU8>,
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
            state: Arc::new(AtomicU8::new(IDLE)),
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
    /// the device; see [`GpuTimer::request`] for the non-blocking way). `None` if the read-back
    /// fails.
    pub fn read_ms(&self, device: &wgpu::Device) -> Option<f64> {
        self.request();
        device.poll(wgpu::PollType::wait_indefinitely()).ok()?;
        self.try_read_ms()
    }

    /// After the submission holding `begin`..`end`: starts reading the timestamps back without
    /// waiting. Record no new `end` into a submission until [`GpuTimer::try_read_ms`] has
    /// returned the time (the buffer is mapped until then). A second call while a read is under
    /// way does nothing.
    pub fn request(&self) {
        if self
            .state
            .compare_exchange(IDLE, PENDING, Ordering::AcqRel, Ordering::Acquire)
            .is_err()
        {
            return;
        }
        let state = self.state.clone();
        self.read
            .slice(..)
            .map_async(wgpu::MapMode::Read, move |r| {
                state.store(if r.is_ok() { MAPPED } else { FAILED }, Ordering::Release);
            });
    }

    /// The GPU time in ms once the read started by [`GpuTimer::request`] has completed (the
    /// device was polled since, by the engine or by `wgpu`'s own submission handling); `None`
    /// while it is still under way, when none was requested, or when it failed (then the timer is
    /// ready for the next request). Never blocks.
    pub fn try_read_ms(&self) -> Option<f64> {
        match self.state.load(Ordering::Acquire) {
            MAPPED => {
                let ticks: Option<[u64; 2]> = crate::gpu_compat::mapped_range(&self.read.slice(..))
                    .map(|data| {
                        [0, 1].map(|i| {
                            u64::from_le_bytes(data[8 * i..8 * i + 8].try_into().expect("8 bytes"))
                        })
                    });
                self.read.unmap();
                self.state.store(IDLE, Ordering::Release);
                ticks.map(|t| t[1].wrapping_sub(t[0]) as f64 * self.period * 1e-6)
            }
            FAILED => {
                self.state.store(IDLE, Ordering::Release);
                None
            }
            _ => None,
        }
    }
}
