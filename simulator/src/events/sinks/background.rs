//! [`BackgroundWriter`]: an [`EventWriter`] on a thread of its own, so that encoding and
//! compressing the file overlap the event model. It receives the same batches in the same order,
//! so the file has the same bytes as one written in place; the writer itself need not be `Send`
//! (it is created on its thread).

use std::io;
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::Arc;
use std::thread::JoinHandle;

use super::{EventWriter, SinkKind};
use crate::events::{Event, EventSink};

/// Events queued for the writer thread before `push` waits (64 MB): enough that the model
/// runs ahead of the writer through a whole batch of frames, bounded whatever the batch.
const MAX_QUEUED: usize = 1 << 22;

/// What the writer thread receives.
enum Message {
    /// Events to write.
    Batch(Vec<Event>),
    /// Complete the file; without it (the queue closed early) the writer is dropped unfinished.
    Finish,
}

/// An [`EventWriter`] running on its own thread (see the module docs).
///
/// A write error stops the thread; the next [`push`](EventSink::push) or
/// [`finish`](BackgroundWriter::finish) returns it. Dropped without `finish`, it waits for the
/// thread, whose writer removes its temporary file.
pub struct BackgroundWriter {
    batches: Option<Sender<Message>>,
    /// Buffers the thread has written, for reuse (each also says the queue went down).
    spare: Receiver<Vec<Event>>,
    /// Events sent and not yet written.
    queued: Arc<AtomicUsize>,
    thread: Option<JoinHandle<io::Result<u64>>>,
}

impl BackgroundWriter {
    /// Start writing `path` as [`EventWriter::create`] does, on a new thread; its errors (an
    /// unwritable folder, ...) are returned here.
    pub fn create(path: &Path, kind: SinkKind) -> io::Result<BackgroundWriter> {
        let (ready_tx, ready_rx) = mpsc::sync_channel::<io::Result<()>>(1);
        let (batch_tx, batch_rx) = mpsc::channel::<Message>();
        let queued = Arc::new(AtomicUsize::new(0));
        let written = Arc::clone(&queued);
        let (spare_tx, spare_rx) = mpsc::channel::<Vec<Event>>();
        let path = path.to_path_buf();
        let thread = std::thread::Builder::new().name("event-writer".into()).spawn(move || {
            let mut sink = match EventWriter::create(&path, kind) {
                Ok(sink) => sink,
                Err(e) => {
                    let _ = ready_tx.send(Err(e));
                    return Ok(0);
                }
            };
            let _ = ready_tx.send(Ok(()));
            for message in batch_rx {
                match message {
                    Message::Batch(batch) => {
                        sink.push(&batch)?; // returning drops the receiver: the next send fails
                        written.fetch_sub(batch.len(), Ordering::AcqRel);
                        let _ = spare_tx.send(batch);
                    }
                    Message::Finish => return sink.finish(),
                }
            }
            Err(io::Error::other("the event file was abandoned")) // dropped: no file
        })?;
        let ready = ready_rx.recv().unwrap_or_else(|_| Err(io::Error::other("the event writer thread stopped")));
        if let Err(e) = ready {
            let _ = thread.join();
            return Err(e);
        }
        Ok(BackgroundWriter { batches: Some(batch_tx), spare: spare_rx, queued, thread: Some(thread) })
    }

    /// Wait for the queued batches, complete the file and move it into place; returns the
    /// number of events written.
    pub fn finish(mut self) -> io::Result<u64> {
        if let Some(tx) = self.batches.take() {
            let _ = tx.send(Message::Finish); // if the thread has stopped, join says why
        }
        self.join()
    }

    /// The thread's result (its first error, or what `finish` returned).
    fn join(&mut self) -> io::Result<u64> {
        match self.thread.take() {
            Some(thread) => thread.join().unwrap_or_else(|_| Err(io::Error::other("the event writer thread panicked"))),
            None => Err(io::Error::other("the event writer has already stopped")),
        }
    }
}

impl EventSink for BackgroundWriter {
    fn push(&mut self, events: &[Event]) -> io::Result<()> {
        if events.is_empty() {
            return Ok(());
        }
        // a full queue: wait for the writer to hand back a buffer (or to stop)
        let mut spare = None;
        while self.queued.load(Ordering::Acquire) >= MAX_QUEUED {
            match self.spare.recv() {
                Ok(b) => spare = Some(b),
                Err(_) => break, // the thread stopped: the send below fails and says why
            }
        }
        let mut batch = spare.or_else(|| self.spare.try_recv().ok()).unwrap_or_default();
        batch.clear();
        batch.extend_from_slice(events);
        self.queued.fetch_add(batch.len(), Ordering::AcqRel);
        let sent = self.batches.as_ref().map(|tx| tx.send(Message::Batch(batch)).is_ok()).unwrap_or(false);
        if sent {
            return Ok(());
        }
        // the thread stopped on an error: report it
        self.batches = None;
        match self.join() {
            Err(e) => Err(e),
            Ok(_) => Err(io::Error::other("the event writer thread stopped")),
        }
    }
}

impl Drop for BackgroundWriter {
    fn drop(&mut self) {
        self.batches = None;
        if let Some(thread) = self.thread.take() {
            let _ = thread.join(); // the unfinished writer removes its temporary file
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::events::sinks::test_util::temp_dir;

    fn events(n: usize, t0: i64) -> Vec<Event> {
        (0..n)
            .map(|i| Event {
                x: (i % 7) as u16,
                y: (i % 5) as u16,
                t_ns: t0 + i as i64,
                p: if i % 3 == 0 { 1 } else { -1 },
            })
            .collect()
    }

    #[test]
    fn same_bytes_as_writing_in_place() {
        let dir = temp_dir("background-same");
        for (kind, name) in [
            (SinkKind::NerfH5, "e.h5"),
            (SinkKind::DsecH5, "d.h5"),
            (SinkKind::Text, "e.txt"),
            (SinkKind::Npz, "e.npz"),
        ] {
            let (a, b) = (dir.join(format!("direct-{name}")), dir.join(format!("thread-{name}")));
            let mut direct = EventWriter::create(&a, kind).unwrap();
            let mut thread = BackgroundWriter::create(&b, kind).unwrap();
            for k in 0..40 {
                let batch = events(3000 + 17 * k, k as i64 * 1_000_000);
                direct.push(&batch).unwrap();
                thread.push(&batch).unwrap();
            }
            assert_eq!(direct.finish().unwrap(), thread.finish().unwrap());
            assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap(), "{name}");
        }
        let hidden: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .flatten()
            .filter(|e| e.file_name().to_string_lossy().starts_with('.'))
            .collect();
        assert!(hidden.is_empty(), "temporary files left: {hidden:?}");
    }

    #[test]
    fn errors_reach_the_caller_and_a_drop_leaves_no_file() {
        let dir = temp_dir("background-errors");
        // an unwritable target: its folder would be inside a file
        std::fs::write(dir.join("file"), "not a folder").unwrap();
        let e = BackgroundWriter::create(&dir.join("file/e.h5"), SinkKind::NerfH5).err().expect("an error");
        assert!(e.to_string().contains("file"), "{e}");
        // dropped unfinished: nothing at the target, no temporary file
        let out = dir.join("dropped.h5");
        let mut w = BackgroundWriter::create(&out, SinkKind::NerfH5).unwrap();
        w.push(&events(100, 0)).unwrap();
        drop(w);
        assert!(!out.exists());
        let left: Vec<_> = std::fs::read_dir(&dir).unwrap().flatten().map(|e| e.file_name()).collect();
        assert_eq!(left, vec![std::ffi::OsString::from("file")], "{left:?}");
    }
}
