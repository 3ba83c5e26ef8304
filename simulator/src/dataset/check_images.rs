//! The PNG folders of the schema check: `images_1/` (required) and `images_sharp_1/` (ours,
//! optional). Only the PNG headers are read (size and colour type), not the pixels.

use std::path::Path;

use image::codecs::png::PngDecoder;
use image::{ColorType, ImageDecoder};

use super::check::Lines;

/// What `images_1/` holds.
pub(super) struct Images {
    /// PNG file names, sorted.
    pub names: Vec<String>,
    /// (width, height) if all images agree on one.
    pub size: Option<(u32, u32)>,
}

/// The sorted `.png` names in `dir`; `None` if it cannot be listed.
fn png_names(dir: &Path) -> Option<Vec<String>> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .ok()?
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.to_ascii_lowercase().ends_with(".png") && !n.starts_with('.'))
        .collect();
    names.sort();
    Some(names)
}

/// Largest decoded image the check reads (bytes): 16384 x 16384 RGBA16 is 2 GiB.
const MAX_DECODED_BYTES: u64 = 1 << 31;

/// The (width, height, colour) of a PNG, decoded in full: a truncated or corrupt image data
/// stream is an error here, not later in the trainer.
fn png_decode(path: &Path) -> Result<(u32, u32, ColorType), String> {
    let file = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let decoder = PngDecoder::new(std::io::BufReader::new(file)).map_err(|e| e.to_string())?;
    let (w, h) = decoder.dimensions();
    let colour = decoder.color_type();
    let bytes = decoder.total_bytes();
    if bytes > MAX_DECODED_BYTES {
        return Err(format!("{w}x{h} {colour:?} decodes to {bytes} bytes, more than the check reads"));
    }
    let mut buf = vec![0u8; bytes as usize];
    decoder.read_image(&mut buf).map_err(|e| format!("image data cannot be decoded: {e}"))?;
    Ok((w, h, colour))
}

/// The number in a file stem's last run of digits (`"00012"` -> 12, `"img_07"` -> 7).
fn trailing_number(name: &str) -> Option<u64> {
    let stem = name.rsplit_once('.').map_or(name, |(s, _)| s);
    let digits: String = stem.chars().rev().take_while(char::is_ascii_digit).collect();
    digits.chars().rev().collect::<String>().parse().ok()
}

/// Check `images_1/`: sequence names, one size, 8-bit RGB. `None` if the folder is missing.
pub(super) fn check_images(dir: &Path, lines: &mut Lines) -> Option<Images> {
    const FILE: &str = "images_1/";
    let Some(names) = png_names(&dir.join("images_1")) else {
        lines.missing(FILE, "write the blurry/sharp views as images_1/00.png, 01.png, ... (8-bit RGB PNG)");
        return None;
    };
    let before = lines.problem_count();
    if names.is_empty() {
        lines.invalid(FILE, "*.png", "no PNG images", "write the views as zero-padded PNGs 00.png, 01.png, ...");
        return Some(Images { names, size: None });
    }
    // Names: numbered, and name order = number order (zero-padded).
    let numbers: Vec<Option<u64>> = names.iter().map(|n| trailing_number(n)).collect();
    if let Some(i) = numbers.iter().position(Option::is_none) {
        lines.invalid(FILE, &names[i], "the name has no sequence number", "name the views 00.png, 01.png, ...");
    } else if let Some(i) = (1..names.len()).find(|&i| numbers[i] <= numbers[i - 1]) {
        lines.invalid(
            FILE,
            &names[i],
            format!("sorts after {} by name but its number is not larger (names not zero-padded?)", names[i - 1]),
            "zero-pad the numbers so that name order is sequence order (00.png ... 15.png)",
        );
    }
    // Headers: one size, 8-bit RGB (RGBA: the loader keeps [..., :3], a warning).
    let (mut size, mut rgba, mut sizes_differ) = (None, Vec::new(), false);
    for name in &names {
        match png_decode(&dir.join("images_1").join(name)) {
            Err(e) => lines.unreadable(&format!("images_1/{name}"), e, "write it again as an 8-bit RGB PNG"),
            Ok((w, h, colour)) => {
                match size {
                    None => size = Some((w, h)),
                    Some(s) if s != (w, h) && !sizes_differ => {
                        sizes_differ = true;
                        lines.invalid(
                            &format!("images_1/{name}"),
                            "size",
                            format!("{w}x{h}, but {} is {}x{}", names[0], s.0, s.1),
                            "render every view at the same resolution",
                        );
                    }
                    Some(_) => {}
                }
                match colour {
                    ColorType::Rgb8 => {}
                    ColorType::Rgba8 => rgba.push(name.clone()),
                    other => lines.invalid(
                        &format!("images_1/{name}"),
                        "colour type",
                        format!("{other:?}, not 8-bit RGB"),
                        "save 8-bit RGB PNGs (the loader divides by 255)",
                    ),
                }
            }
        }
    }
    if !rgba.is_empty() {
        lines.warn(
            FILE,
            format!(
                "{} of {} images are RGBA (e.g. {}); the format asks for RGB, the alpha is dropped",
                rgba.len(),
                names.len(),
                rgba[0]
            ),
        );
    }
    let size = if sizes_differ { None } else { size };
    if lines.problem_count() == before {
        let (w, h) = size.unwrap_or_default();
        lines.ok(FILE, format!("{} PNG images {}..{}, {w}x{h}, 8-bit", names.len(), names[0], names[names.len() - 1]));
    }
    Some(Images { names, size })
}

/// Check `images_sharp_1/` if present: the same names and size as `images_1/`.
pub(super) fn check_sharp_images(dir: &Path, images: &Images, lines: &mut Lines) {
    const FILE: &str = "images_sharp_1/";
    let Some(names) = png_names(&dir.join("images_sharp_1")) else {
        lines.0.push(super::check::CheckLine::Absent {
            file: FILE.into(),
            detail: "evblur's sharp version of every view (public datasets have none)".into(),
        });
        return;
    };
    let before = lines.problem_count();
    if names != images.names {
        let missing: Vec<&String> = images.names.iter().filter(|n| !names.contains(n)).collect();
        let extra: Vec<&String> = names.iter().filter(|n| !images.names.contains(n)).collect();
        lines.invalid(
            FILE,
            "file names",
            format!("differ from images_1/: missing {missing:?}, extra {extra:?}"),
            "write one sharp image per view, named as in images_1/",
        );
    }
    for name in &names {
        let file = format!("images_sharp_1/{name}");
        match png_decode(&dir.join("images_sharp_1").join(name)) {
            Err(e) => lines.unreadable(&file, e, "write it again as an 8-bit RGB PNG"),
            Ok((w, h, colour)) => {
                if images.size.is_some_and(|s| s != (w, h)) {
                    let (iw, ih) = images.size.unwrap_or_default();
                    lines.invalid(&file, "size", format!("{w}x{h}, images_1/ is {iw}x{ih}"), "render at the same size");
                }
                if !matches!(colour, ColorType::Rgb8 | ColorType::Rgba8) {
                    lines.invalid(&file, "colour type", format!("{colour:?}, not 8-bit RGB"), "save 8-bit RGB PNGs");
                }
            }
        }
    }
    if lines.problem_count() == before {
        lines.ok(FILE, format!("{} sharp PNG images, names and size as images_1/", names.len()));
    }
}
