//! The arguments the crack-scene examples share: `[WIDTHxHEIGHT] [REPEATS]`.

/// The frame size (default 320x240) and the number of timed repeats (default 7).
pub fn size_and_repeats() -> ((u32, u32), usize) {
    let mut args = std::env::args().skip(1);
    let size = args
        .next()
        .and_then(|s| {
            let (w, h) = s.split_once('x')?;
            Some((w.parse().ok()?, h.parse().ok()?))
        })
        .unwrap_or((320, 240));
    let repeats = args.next().and_then(|r| r.parse().ok()).unwrap_or(7);
    (size, repeats)
}
