//! The RPG/ECD text format: one line `t x y p` per event, `t` in seconds with 9 decimals (exact
//! nanoseconds, formatted from the integer time), `p` 1 for ON and 0 for OFF.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::Path;

use super::{io_err, AtomicTarget};
use crate::events::{Event, EventSink};

/// Writes `t x y p` lines through a buffer.
pub struct TextSink {
    // Field order is drop order: the file, then the temporary-file guard.
    out: Option<BufWriter<File>>,
    n: u64,
    target: AtomicTarget,
}

impl TextSink {
    /// Start writing `path` (through a temporary sibling).
    pub fn create(path: &Path) -> io::Result<TextSink> {
        let target = AtomicTarget::new(path)?;
        let file = File::create(&target.tmp).map_err(|e| io_err(&target.tmp, "cannot create", e))?;
        Ok(TextSink { out: Some(BufWriter::with_capacity(1 << 20, file)), n: 0, target })
    }

    /// Flush the file and move it into place; returns the number of events written.
    pub fn finish(mut self) -> io::Result<u64> {
        let out = self.out.take().expect("open until finish");
        let file = out.into_inner().map_err(|e| io_err(&self.target.tmp, "cannot write", e.error()))?;
        file.sync_all().map_err(|e| io_err(&self.target.tmp, "cannot write", e))?;
        drop(file);
        self.target.commit_ref()?;
        Ok(self.n)
    }
}

/// Write `t_ns` as seconds with exactly 9 decimals.
fn write_seconds(out: &mut impl Write, t_ns: i64) -> io::Result<()> {
    let sign = if t_ns < 0 { "-" } else { "" };
    let a = t_ns.unsigned_abs();
    write!(out, "{sign}{}.{:09}", a / 1_000_000_000, a % 1_000_000_000)
}

impl EventSink for TextSink {
    fn push(&mut self, events: &[Event]) -> io::Result<()> {
        let out = self.out.as_mut().expect("open until finish");
        let tmp = &self.target.tmp;
        for e in events {
            write_seconds(out, e.t_ns).map_err(|err| io_err(tmp, "cannot write", err))?;
            writeln!(out, " {} {} {}", e.x, e.y, u8::from(e.p > 0)).map_err(|err| io_err(tmp, "cannot write", err))?;
        }
        self.n += events.len() as u64;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_util::{files, known_events, temp_dir};
    use super::*;

    #[test]
    fn seconds_have_nine_exact_decimals() {
        let fmt = |t| {
            let mut v = Vec::new();
            write_seconds(&mut v, t).unwrap();
            String::from_utf8(v).unwrap()
        };
        assert_eq!(fmt(0), "0.000000000");
        assert_eq!(fmt(1_000_000_001), "1.000000001");
        assert_eq!(fmt(123_456_789_012_345_678), "123456789.012345678");
        assert_eq!(fmt(-1_500_000_000), "-1.500000000");
    }

    #[test]
    fn text_round_trips() {
        let dir = temp_dir("text");
        let events = known_events(3000, 2_000_000_123);
        let path = dir.join("events.txt");
        let mut sink = TextSink::create(&path).unwrap();
        for batch in events.chunks(500) {
            sink.push(batch).unwrap();
        }
        assert!(!path.exists());
        assert_eq!(sink.finish().unwrap(), 3000);
        assert_eq!(files(&dir), ["events.txt"]);
        let text = std::fs::read_to_string(&path).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), events.len());
        for (line, e) in lines.iter().zip(&events) {
            let f: Vec<&str> = line.split(' ').collect();
            let (s, ns) = f[0].split_once('.').unwrap();
            assert_eq!(ns.len(), 9, "{line}");
            assert_eq!(s.parse::<i64>().unwrap() * 1_000_000_000 + ns.parse::<i64>().unwrap(), e.t_ns);
            assert_eq!(f[1].parse::<u16>().unwrap(), e.x);
            assert_eq!(f[2].parse::<u16>().unwrap(), e.y);
            assert_eq!(f[3], if e.p > 0 { "1" } else { "0" });
        }
    }

    #[test]
    fn unfinished_text_leaves_no_file() {
        let dir = temp_dir("text-drop");
        let mut sink = TextSink::create(&dir.join("e.txt")).unwrap();
        sink.push(&known_events(100, 0)).unwrap();
        drop(sink);
        assert!(files(&dir).is_empty());
    }
}
