//! The only place this crate submits work to a queue or waits: [`submit`], [`wait`] and
//! [`block_on`]. The middleware path — every renderer's `prepare` and `render` — calls none of
//! them: it writes buffers with `Queue::write_buffer` (staged, lands before the host's next
//! submission; WebGPU specification, "writeBuffer") and records into the host's encoder or pass.
//! Only constructors (error scopes), the headless host ([`crate::headless::RenderTarget`] frames,
//! [`crate::headless::read_back`]) and test readbacks come here.
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

#[cfg(test)]
mod tests {
    #[test]
    fn no_other_file_submits_or_waits() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
        let mut checked = 0;
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
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
