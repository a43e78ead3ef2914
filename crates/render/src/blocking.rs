//! The only place this crate submits work to a queue or waits: [`submit`], [`wait`] and
//! [`block_on`]. The middleware path — every renderer's `prepare` and `render` — calls none of
//! them: it writes buffers with `Queue::write_buffer` (staged, lands before the host's next
//! submission; WebGPU specification, "writeBuffer") and records into the host's encoder or pass.
//! Only constructors (error scopes), the headless host ([`crate::headless::RenderTarget`] frames,
//! [`crate::headless::read_back`]) and test readbacks come here, and the buffer readbacks that
//! wait ([`map_for_reading`], `read_buffer`) live here.
//!
//! Each call is counted per thread ([`blocking_calls_on_this_thread`]), so a test can run host
//! frames and check that the count did not move; the unit test below checks that no other file
//! of the crate submits or waits on its own.

use std::cell::Cell;

use crate::RenderError;

thread_local! {
    static CALLS: Cell<u64> = const { Cell::new(0) };
}

fn count() {
    CALLS.with(|c| c.set(c.get() + 1));
}

/// Submits `buffers` to `queue` (counted).
pub(crate) fn submit<I: IntoIterator<Item = wgpu::CommandBuffer>>(
    queue: &wgpu::Queue,
    buffers: I,
) -> wgpu::SubmissionIndex {
    count();
    queue.submit(buffers)
}

/// Waits until the device has finished all submitted work and run its callbacks (counted).
pub(crate) fn wait(device: &wgpu::Device) -> Result<(), RenderError> {
    count();
    device.poll(wgpu::PollType::wait_indefinitely()).map(|_| ()).map_err(|e| RenderError::Gpu { what: e.to_string() })
}

/// Blocks the thread on `future` (counted): error-scope pops and adapter requests.
pub(crate) fn block_on<F: std::future::Future>(future: F) -> F::Output {
    count();
    pollster::block_on(future)
}

/// How many times this thread has submitted, waited or blocked inside this crate. For tests:
/// a host frame of `prepare` + `render` calls must leave it unchanged.
#[cfg(feature = "testing")]
pub fn blocking_calls_on_this_thread() -> u64 {
    CALLS.with(Cell::get)
}

#[cfg(feature = "testing")]
/// Copies the first `count` elements of `source` (a `COPY_SRC` buffer) into a staging buffer,
/// submits, waits and returns them; `what` names the readback in errors. For tests and tools.
pub(crate) fn read_buffer<T: bytemuck::Pod>(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    source: &wgpu::Buffer,
    count: u64,
    what: &str,
) -> Result<Vec<T>, RenderError> {
    let bytes = count * std::mem::size_of::<T>() as u64;
    let staging = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(what),
        size: bytes,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(what) });
    encoder.copy_buffer_to_buffer(source, 0, &staging, 0, bytes);
    submit(queue, [encoder.finish()]);
    map_for_reading(device, &staging, what)?;
    let out = {
        let view = staging.get_mapped_range(..).map_err(|e| RenderError::Gpu { what: e.to_string() })?;
        bytemuck::cast_slice(&view).to_vec()
    };
    staging.unmap();
    Ok(out)
}

/// Maps `buffer` (a `MAP_READ` buffer whose copy was already submitted) and waits until the map
/// completes; `what` names the readback in errors.
pub(crate) fn map_for_reading(device: &wgpu::Device, buffer: &wgpu::Buffer, what: &str) -> Result<(), RenderError> {
    let (tx, rx) = std::sync::mpsc::channel();
    buffer.map_async(wgpu::MapMode::Read, .., move |r| {
        let _ = tx.send(r);
    });
    wait(device)?;
    match rx.recv() {
        Ok(Ok(())) => Ok(()),
        Ok(Err(e)) => Err(RenderError::Gpu { what: format!("{what}: mapping failed: {e}") }),
        Err(_) => Err(RenderError::Gpu { what: format!("{what}: mapping never completed") }),
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn no_other_file_submits_or_waits() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
        let mut checked = 0;
        // Every source file, submodules' folders included.
        let mut paths = Vec::new();
        let mut folders = vec![dir];
        while let Some(folder) = folders.pop() {
            for entry in std::fs::read_dir(&folder).unwrap() {
                let path = entry.unwrap().path();
                if path.is_dir() { folders.push(path) } else { paths.push(path) }
            }
        }
        for path in paths {
            if path.extension().is_none_or(|e| e != "rs") || path.ends_with("blocking.rs") {
                continue;
            }
            let text = std::fs::read_to_string(&path).unwrap();
            for needle in [".submit(", ".poll(", "pollster::", "block_on("] {
                let hits: Vec<_> = text
                    .lines()
                    .enumerate()
                    // Comments may show host code (the crate documentation's example submits).
                    .filter(|(_, l)| !l.trim_start().starts_with("//"))
                    .filter(|(_, l)| l.contains(needle) && !l.contains("blocking::"))
                    .map(|(i, _)| i + 1)
                    .collect();
                assert!(hits.is_empty(), "{}: `{needle}` outside crate::blocking on lines {hits:?}", path.display());
            }
            checked += 1;
        }
        assert!(checked >= 9, "checked only {checked} source files");
    }
}
