//! [`VizSink`] on a hand-made event list with known images and rate table.

use super::super::test_util::{files, temp_dir};
use super::*;

const MS: i64 = 1_000_000;

fn ev(x: u16, y: u16, t_ns: i64, p: i8) -> Event {
    Event { x, y, t_ns, p }
}

/// 4x3 pixels; windows of 10 ms starting at the 10 ms window; window 1 ([20, 30) ms) is empty.
fn known() -> Vec<Event> {
    vec![
        // Window 0: [10, 20) ms.
        ev(0, 0, 12 * MS, 1),
        ev(1, 0, 12 * MS + MS / 2, -1),
        ev(1, 0, 13 * MS, -1),
        ev(2, 0, 13 * MS, 1),
        ev(2, 0, 15 * MS, -1),
        ev(3, 0, 15 * MS, 1),
        ev(3, 0, 15 * MS + 100_000, 1),
        ev(3, 0, 15 * MS + 200_000, 1),
        ev(3, 0, 15 * MS + 300_000, 1),
        ev(3, 0, 15 * MS + 400_000, 1),
        ev(0, 1, 19 * MS, 1),
        ev(0, 1, 19 * MS + MS / 2, 1),
        ev(0, 1, 20 * MS - 1, -1),
        // Window 2: [30, 40) ms.
        ev(3, 2, 30 * MS, -1),
        ev(0, 2, 40 * MS - 1, 1),
    ]
}

fn config(dir: &Path) -> VizConfig {
    VizConfig { dir: dir.to_path_buf(), window_ns: 10 * MS, rate_bin_ns: MS, saturate_count: 4 }
}

fn pixels(path: &Path) -> image::RgbImage {
    image::open(path).unwrap().to_rgb8()
}

#[test]
fn windows_rate_and_summary_match_the_hand_count() {
    let dir = temp_dir("viz");
    let mut sink = VizSink::create(config(&dir), 4, 3).unwrap();
    for batch in known().chunks(4) {
        sink.push(batch).unwrap();
    }
    sink.push(&[]).unwrap();
    let s = sink.finish().unwrap();

    // One image per window from the first event's to the last's, the empty one included.
    assert_eq!(files(&dir), ["event_rate.csv", "events_000000.png", "events_000001.png", "events_000002.png"]);

    // Window 0: majority colour, strength min(n, 4) / 4 of the non-colour channels.
    let w0 = pixels(&dir.join("events_000000.png"));
    assert_eq!(w0.dimensions(), (4, 3));
    assert_eq!(w0.get_pixel(0, 0).0, [255, 191, 191], "1 ON: light red");
    assert_eq!(w0.get_pixel(1, 0).0, [128, 128, 255], "2 OFF: blue at half strength");
    assert_eq!(w0.get_pixel(2, 0).0, [255, 128, 255], "1 ON + 1 OFF: magenta");
    assert_eq!(w0.get_pixel(3, 0).0, [255, 0, 0], "5 ON: saturated red");
    assert_eq!(w0.get_pixel(0, 1).0, [255, 64, 64], "2 ON + 1 OFF: red by majority, strength 3/4");
    for (x, y) in [(1, 1), (3, 2), (0, 2)] {
        assert_eq!(w0.get_pixel(x, y).0, [255; 3], "({x}, {y}) has no event in window 0");
    }
    // Window 1 is blank, window 2 has only its own events.
    assert!(pixels(&dir.join("events_000001.png")).pixels().all(|p| p.0 == [255; 3]));
    let w2 = pixels(&dir.join("events_000002.png"));
    assert_eq!(w2.get_pixel(3, 2).0, [191, 191, 255]);
    assert_eq!(w2.get_pixel(0, 2).0, [255, 191, 191]);
    assert_eq!(w2.pixels().filter(|p| p.0 != [255; 3]).count(), 2);

    // Rate table: 1 ms bins from 12 ms to 39 ms, empty bins included.
    let csv = std::fs::read_to_string(dir.join(RATE_CSV)).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines[0], "t_start_s,on,off,total,rate_hz");
    assert_eq!(lines.len(), 1 + 28);
    let row = |ms: usize| lines[1 + ms - 12];
    assert_eq!(row(12), "0.012000000,1,1,2,2000");
    assert_eq!(row(13), "0.013000000,1,1,2,2000");
    assert_eq!(row(14), "0.014000000,0,0,0,0");
    assert_eq!(row(15), "0.015000000,5,1,6,6000");
    assert_eq!(row(19), "0.019000000,2,1,3,3000");
    assert_eq!(row(30), "0.030000000,0,1,1,1000");
    assert_eq!(row(39), "0.039000000,1,0,1,1000");
    let total: u64 = lines[1..].iter().map(|l| l.split(',').nth(3).unwrap().parse::<u64>().unwrap()).sum();
    assert_eq!(total, 15);

    assert_eq!((s.on, s.off, s.windows), (10, 5, 3));
    assert_eq!(s.t_first_window_ns, Some(10 * MS));
    assert_eq!((s.peak_rate_hz, s.peak_t_ns), (6000.0, 15 * MS));
    assert!((s.mean_rate_hz - 15.0 / 0.028).abs() < 1e-9, "{}", s.mean_rate_hz);
}

#[test]
fn unfinished_viz_leaves_only_the_closed_windows() {
    let dir = temp_dir("viz-drop");
    let mut sink = VizSink::create(config(&dir), 4, 3).unwrap();
    sink.push(&known()).unwrap();
    drop(sink);
    // Windows 0 and 1 were closed by later events; window 2 and the rate table need finish().
    assert_eq!(files(&dir), ["events_000000.png", "events_000001.png"]);
}

#[test]
fn no_events_write_an_empty_rate_table_and_no_image() {
    let dir = temp_dir("viz-empty");
    let s = VizSink::create(config(&dir), 4, 3).unwrap().finish().unwrap();
    assert_eq!(files(&dir), ["event_rate.csv"]);
    assert_eq!(std::fs::read_to_string(dir.join(RATE_CSV)).unwrap(), "t_start_s,on,off,total,rate_hz\n");
    assert_eq!(s, VizSummary::default());
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let dir = temp_dir("viz-bad");
    let mut sink = VizSink::create(config(&dir), 4, 3).unwrap();
    let e = sink.push(&[ev(4, 0, 0, 1)]).unwrap_err().to_string();
    assert!(e.contains("(4, 0)") && e.contains("4x3"), "{e}");
    sink.push(&[ev(0, 0, 25 * MS, 1)]).unwrap();
    let e = sink.push(&[ev(0, 0, 5 * MS, 1)]).unwrap_err().to_string();
    assert!(e.contains("back in time"), "{e}");

    let mut cfg = config(&dir);
    cfg.window_ns = 0;
    let e = VizSink::create(cfg, 4, 3).err().unwrap().to_string();
    assert!(e.contains("window_ns = 0") && e.contains("positive"), "{e}");
    let mut cfg = config(&dir);
    cfg.saturate_count = 0;
    assert!(cfg.validate().is_err());
}
