//! Events and where they go: the [`EventSink`] trait, an in-memory [`VecSink`] and a
//! [`CountingSink`] that keeps only the counts (benchmarks).

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
