//! Events and where they go: the [`EventSink`] trait, an in-memory [`VecSink`], a
//! [`CountingSink`] that keeps only the counts (benchmarks) and a [`Tee`] that feeds two sinks.

/// One event: the pixel, the time and the sign of the log-intensity change.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Event {
    /// Column, 0 at the left.
    pub x: u16,
    /// Row, 0 at the top.
    pub y: u16,
    /// Time in integer nanoseconds (the same clock as the frame times).
    pub t_ns: i64,
    /// Polarity: +1 (ON, brighter) or -1 (OFF, darker).
    pub p: i8,
}

impl Event {
    /// The global output order: time, then row, then column (a stable sort keeps the per-pixel
    /// emission order as the last tie-break).
    #[inline]
    pub fn order_key(&self) -> (i64, u32) {
        (self.t_ns, (self.y as u32) << 16 | self.x as u32)
    }
}

/// Where the simulator writes events. It receives the events of one frame interval at a time,
/// already globally time-sorted; successive calls never go back in time.
pub trait EventSink {
    /// Take a batch of time-sorted events (may be empty).
    fn push(&mut self, events: &[Event]) -> std::io::Result<()>;
}

impl<S: EventSink + ?Sized> EventSink for &mut S {
    fn push(&mut self, events: &[Event]) -> std::io::Result<()> {
        (**self).push(events)
    }
}

/// Keeps every event in memory (tests, small sequences).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VecSink {
    /// All events received so far, in order.
    pub events: Vec<Event>,
}

impl EventSink for VecSink {
    fn push(&mut self, events: &[Event]) -> std::io::Result<()> {
        self.events.extend_from_slice(events);
        Ok(())
    }
}

/// Counts events by polarity and keeps nothing else (benchmarks).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CountingSink {
    /// ON events received.
    pub on: u64,
    /// OFF events received.
    pub off: u64,
    /// Time of the last event received, ns (None before any).
    pub last_t_ns: Option<i64>,
}

impl EventSink for CountingSink {
    fn push(&mut self, events: &[Event]) -> std::io::Result<()> {
        let on = events.iter().filter(|e| e.p > 0).count() as u64;
        self.on += on;
        self.off += events.len() as u64 - on;
        if let Some(e) = events.last() {
            self.last_t_ns = Some(e.t_ns);
        }
        Ok(())
    }
}

/// Forwards every batch, unchanged, to two sinks: `a` first, then `b` (e.g. an event file and a
/// visualisation in one run). An error of `a` stops the batch before `b` sees it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Tee<A, B> {
    /// The first sink.
    pub a: A,
    /// The second sink.
    pub b: B,
}

impl<A: EventSink, B: EventSink> EventSink for Tee<A, B> {
    fn push(&mut self, events: &[Event]) -> std::io::Result<()> {
        self.a.push(events)?;
        self.b.push(events)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Keeps each batch as it came.
    #[derive(Default)]
    struct Batches(Vec<Vec<Event>>);

    impl EventSink for Batches {
        fn push(&mut self, events: &[Event]) -> std::io::Result<()> {
            self.0.push(events.to_vec());
            Ok(())
        }
    }

    #[test]
    fn tee_forwards_identical_batches_to_both() {
        let ev = |i: i64| Event { x: i as u16, y: 2 * i as u16, t_ns: 100 * i, p: if i % 3 == 0 { 1 } else { -1 } };
        let batches: Vec<Vec<Event>> = vec![(0..4).map(ev).collect(), vec![], (4..9).map(ev).collect()];
        let mut tee = Tee { a: Batches::default(), b: Tee { a: CountingSink::default(), b: Batches::default() } };
        for b in &batches {
            tee.push(b).unwrap();
        }
        assert_eq!(tee.a.0, batches);
        assert_eq!(tee.b.b.0, batches);
        assert_eq!((tee.b.a.on, tee.b.a.off), (3, 6));
    }
}
