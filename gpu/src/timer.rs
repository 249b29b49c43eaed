//! The GPU's own clock: a timestamp at the start and the end of every dispatch's compute pass,
//! summed until taken (`FrameStats::device_seconds`: the kernels' time alone, without the
//! uniform writes, the waits and the read-back that the frame's wall time also holds). Only
//! where the adapter has timestamp queries (`wgpu::Features::TIMESTAMP_QUERY`).

use crate::context::GpuContext;
use crate::GpuError;

/// Dispatches timed between two read-backs of the timestamps.
const PAIRS: u32 = 256;

pub(crate) struct KernelTimer {
    queries: wgpu::QuerySet,
    /// Where the query set resolves to (`QUERY_RESOLVE`), copied to a mappable buffer.
    resolved: wgpu::Buffer,
    read: wgpu::Buffer,
    /// Nanoseconds per tick (`Queue::get_timestamp_period`).
    period_ns: f64,
    /// Pairs written since the last `flush`.
    pending: u32,
    /// Seconds summed since the last `take`.
    seconds: f64,
}

impl KernelTimer {
    /// A timer, if the device was created with timestamp queries.
    pub(crate) fn new(device: &wgpu::Device, queue: &wgpu::Queue) -> Option<Self> {
        if !device.features().contains(wgpu::Features::TIMESTAMP_QUERY) {
            return None;
        }
        let bytes = 2 * PAIRS as u64 * std::mem::size_of::<u64>() as u64;
        let buffer = |label, usage| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes,
                usage,
                mapped_at_creation: false,
            })
        };
        Some(KernelTimer {
            queries: device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("kernel timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: 2 * PAIRS,
            }),
            resolved: buffer(
                "kernel timestamps",
                wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            ),
            read: buffer(
                "kernel timestamps read-back",
                wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            ),
            period_ns: queue.get_timestamp_period() as f64,
            pending: 0,
            seconds: 0.0,
        })
    }

    /// The timestamp writes of the next compute pass. Call `flush_if_full` after submitting
    /// it.
    pub(crate) fn pass_writes(&mut self) -> wgpu::ComputePassTimestampWrites<'_> {
        let k = self.pending;
        self.pending += 1;
        wgpu::ComputePassTimestampWrites {
            query_set: &self.queries,
            beginning_of_pass_write_index: Some(2 * k),
            end_of_pass_write_index: Some(2 * k + 1),
        }
    }

    /// `flush` once every pair of the query set has been written.
    pub(crate) fn flush_if_full(&mut self, ctx: &GpuContext) -> Result<(), GpuError> {
        if self.pending >= PAIRS {
            self.flush(ctx)?;
        }
        Ok(())
    }

    /// Resolve the pairs written so far, read them back and add their spans to the sum.
    pub(crate) fn flush(&mut self, ctx: &GpuContext) -> Result<(), GpuError> {
        if self.pending == 0 {
            return Ok(());
        }
        let n = 2 * self.pending;
        let bytes = n as u64 * std::mem::size_of::<u64>() as u64;
        let mut encoder = ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("kernel timestamps"),
            });
        encoder.resolve_query_set(&self.queries, 0..n, &self.resolved, 0);
        let ticks: u64 =
            ctx.read_back_into(encoder, &self.resolved, &self.read, bytes, |data| {
                let stamps: &[u64] = bytemuck::cast_slice(data);
                // A pass whose end reads before its start (a clock that wrapped or was reset)
                // counts nothing rather than a wrapped-around span.
                stamps
                    .chunks_exact(2)
                    .map(|p| p[1].saturating_sub(p[0]))
                    .sum()
            })?;
        self.seconds += ticks as f64 * self.period_ns * 1e-9;
        self.pending = 0;
        Ok(())
    }

    /// The seconds summed since the last call (every written pair flushed first).
    pub(crate) fn take(&mut self, ctx: &GpuContext) -> Result<f64, GpuError> {
        self.flush(ctx)?;
        Ok(std::mem::take(&mut self.seconds))
    }
}
