//! How a frame's data reaches the GPU (docs/design.md "One upload per frame"). A renderer's own
//! setters write with `queue.write_buffer` ([`Upload::Queue`]); a [`crate::SceneRenderer`]
//! collects every write of a frame, for all its packs, into one staging area ([`FrameUpload`])
//! and uploads it with a single `queue.write_buffer`, then records one buffer-to-buffer copy per
//! write into the host's encoder, ahead of the frame's compute passes. wgpu allocates inside each
//! `write_buffer` (docs/performance.md), so one upload instead of one per buffer is most of what
//! a frame allocates less.

use crate::RenderError;

/// `wgpu::COPY_BUFFER_ALIGNMENT` as a `usize`: offsets and sizes of buffer copies are multiples
/// of it (every write here is of 4-byte words).
const ALIGN: usize = wgpu::COPY_BUFFER_ALIGNMENT as usize;

/// Where a renderer's writes go.
pub(crate) enum Upload<'a> {
    /// Straight to the queue: each write is its own `queue.write_buffer`, landing before the
    /// queue's next submission.
    Queue(&'a wgpu::Queue),
    /// Into a frame's one upload, copied into place by [`FrameUpload::flush`]'s commands.
    Frame(&'a mut FrameUpload),
}

impl Upload<'_> {
    /// Whether writes are collected into one upload. A collected write reaches the GPU only if
    /// the host submits the encoder it was flushed into, so values that renderers skip writing
    /// while unchanged are written every frame instead (a few bytes of the one upload).
    pub(crate) fn collected(&self) -> bool {
        matches!(self, Upload::Frame(_))
    }

    /// Writes `bytes` (a multiple of 4 long) into `dst` at `offset`.
    pub(crate) fn write(&mut self, dst: &wgpu::Buffer, offset: u64, bytes: &[u8]) {
        match self {
            Upload::Queue(queue) => queue.write_buffer(dst, offset, bytes),
            Upload::Frame(frame) => frame.stage(dst, offset, bytes.len()).copy_from_slice(bytes),
        }
    }

    /// Writes `chunks` of `N` bytes one after another into `dst` from `offset`, straight into
    /// the staging memory (no allocation). `what` names the data in an error (the queue refusing
    /// the staging memory).
    pub(crate) fn write_chunks<const N: usize>(
        &mut self,
        dst: &wgpu::Buffer,
        offset: u64,
        chunks: impl ExactSizeIterator<Item = [u8; N]>,
        what: &str,
    ) -> Result<(), RenderError> {
        let len = chunks.len() * N;
        let Some(size) = wgpu::BufferSize::new(len as u64) else { return Ok(()) };
        match self {
            Upload::Queue(queue) => {
                let Some(mut view) = queue.write_buffer_with(dst, offset, size) else {
                    return Err(RenderError::Gpu { what: format!("the {what} upload was refused") });
                };
                for (i, chunk) in chunks.enumerate() {
                    view.slice(i * N..(i + 1) * N).copy_from_slice(&chunk);
                }
            }
            Upload::Frame(frame) => {
                let out = frame.stage(dst, offset, len);
                for (o, chunk) in out.chunks_exact_mut(N).zip(chunks) {
                    o.copy_from_slice(&chunk);
                }
            }
        }
        Ok(())
    }
}

/// One frame's writes: their bytes back to back, where each goes, and the GPU buffer they are
/// uploaded into. Its memory grows to the largest frame and is then reused, so a steady frame
/// allocates nothing here.
#[derive(Debug, Default)]
pub(crate) struct FrameUpload {
    bytes: Vec<u8>,
    copies: Vec<PendingCopy>,
    buffer: Option<wgpu::Buffer>,
}

#[derive(Debug)]
struct PendingCopy {
    /// A handle to the destination (a reference count, not a new buffer).
    dst: wgpu::Buffer,
    dst_offset: u64,
    src_offset: u64,
    size: u64,
}

impl FrameUpload {
    /// Reserves `len` bytes for `dst` at `offset` and returns them to fill.
    fn stage(&mut self, dst: &wgpu::Buffer, offset: u64, len: usize) -> &mut [u8] {
        debug_assert!(
            len.is_multiple_of(ALIGN) && offset.is_multiple_of(ALIGN as u64),
            "buffer writes are of 4-byte words"
        );
        let start = self.bytes.len().next_multiple_of(ALIGN);
        self.bytes.resize(start + len, 0);
        self.copies.push(PendingCopy {
            dst: dst.clone(),
            dst_offset: offset,
            src_offset: start as u64,
            size: len as u64,
        });
        &mut self.bytes[start..]
    }

    /// Uploads the frame's writes with one `queue.write_buffer` and records their copies into
    /// `encoder`, then starts the next frame. Creates (or grows) the upload buffer on `device`
    /// when the frame is larger than any before. Does not submit or wait.
    pub(crate) fn flush(&mut self, device: &wgpu::Device, queue: &wgpu::Queue, encoder: &mut wgpu::CommandEncoder) {
        if self.copies.is_empty() {
            self.bytes.clear();
            return;
        }
        let needed = self.bytes.len() as u64;
        if self.buffer.as_ref().is_none_or(|b| b.size() < needed) {
            self.buffer = Some(device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("furbake frame upload"),
                size: needed.next_power_of_two().max(256),
                usage: wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }));
        }
        let Some(buffer) = &self.buffer else { return };
        queue.write_buffer(buffer, 0, &self.bytes);
        for c in self.copies.drain(..) {
            encoder.copy_buffer_to_buffer(buffer, c.src_offset, &c.dst, c.dst_offset, c.size);
        }
        self.bytes.clear();
    }

    /// Drops the writes made since the last flush (a frame that failed its checks).
    pub(crate) fn discard(&mut self) {
        self.copies.clear();
        self.bytes.clear();
    }
}

/// An iterator whose length is known though its type cannot say so (a filter, a flat map): the
/// length `.1` it is given, which must be exact.
pub(crate) struct ExactLen<I>(pub I, pub usize);

impl<I: Iterator> Iterator for ExactLen<I> {
    type Item = I::Item;

    fn next(&mut self) -> Option<I::Item> {
        let item = self.0.next();
        if item.is_some() {
            self.1 -= 1;
        }
        item
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        (self.1, Some(self.1))
    }
}

impl<I: Iterator> ExactSizeIterator for ExactLen<I> {}
