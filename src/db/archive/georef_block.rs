//! The georeferencing block: the [`Georef`] an archive built from a georeferenced DEM stores
//! right after the header's fixed part, the header's length field counting it.
//!
//! | offset | type | field |
//! | ---: | --- | --- |
//! | 0 | u32 | units: 0 degrees, 1 linear, 2 Web Mercator |
//! | 4 | u32 | bytes `n` of the CRS's name, `1 ..= 1024` |
//! | 8 | f64 | metres per CRS unit (1 for degrees) |
//! | 16 | f64, f64 | CRS x, y of sample (0, 0) |
//! | 32 | f64, f64 | CRS units between columns, between rows |
//! | 48 | `n` bytes | the CRS's name, UTF-8 |
//! | 48 + n | u32 | CRC-32 of the block's bytes before it |

use crate::db::dem::Units;
use crate::db::georef::Georef;

/// Bytes of the block besides the CRS's name.
const FIXED: usize = 52;
/// The shortest block: a one-byte name.
pub const MIN_LEN: usize = FIXED + 1;
/// The longest CRS name stored, bytes.
pub const MAX_CRS_NAME: usize = 1024;
/// The longest block.
pub const MAX_LEN: usize = FIXED + MAX_CRS_NAME;
/// The largest CRS coordinate or cell stored, in size: past any projected CRS's range.
const MAX_COORDINATE: f64 = 1e9;

/// Bytes of `georef`'s block.
pub fn len(georef: &Georef) -> usize {
    FIXED + georef.crs.len().min(MAX_CRS_NAME)
}

/// `georef`'s block; a name longer than [`MAX_CRS_NAME`] is cut at a character boundary.
pub fn to_bytes(georef: &Georef) -> Vec<u8> {
    let mut end = georef.crs.len().min(MAX_CRS_NAME);
    while !georef.crs.is_char_boundary(end) {
        end -= 1;
    }
    let name = &georef.crs.as_bytes()[..end];
    let (kind, metres) = match georef.units {
        Units::Degrees => (0u32, 1.0),
        Units::Linear(m) => (1, m),
        Units::WebMercator(m) => (2, m),
    };
    let mut b = Vec::with_capacity(FIXED + name.len());
    b.extend_from_slice(&kind.to_le_bytes());
    b.extend_from_slice(&(name.len() as u32).to_le_bytes());
    for v in [
        metres,
        georef.first.0,
        georef.first.1,
        georef.cell.0,
        georef.cell.1,
    ] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b.extend_from_slice(name);
    let crc = crc32fast::hash(&b);
    b.extend_from_slice(&crc.to_le_bytes());
    b
}

/// The georeferencing a block holds, or what is wrong with it.
pub fn parse(bytes: &[u8]) -> Result<Georef, String> {
    if !(FIXED..=MAX_LEN).contains(&bytes.len()) {
        return Err(format!(
            "a georeferencing block of {} bytes, not {FIXED} ..= {MAX_LEN}",
            bytes.len()
        ));
    }
    let u = |k: usize| u32::from_le_bytes(bytes[k..k + 4].try_into().expect("4 bytes"));
    let f = |k: usize| f64::from_le_bytes(bytes[k..k + 8].try_into().expect("8 bytes"));
    let end = bytes.len() - 4;
    if crc32fast::hash(&bytes[..end]) != u(end) {
        return Err("georeferencing checksum mismatch (corrupt georeferencing)".into());
    }
    let n = u(4) as usize;
    if n == 0 || FIXED + n != bytes.len() {
        return Err(format!(
            "a CRS name of {n} bytes in a georeferencing block of {} bytes",
            bytes.len()
        ));
    }
    let metres = f(8);
    if !(metres.is_finite() && metres > 0.0 && metres < MAX_COORDINATE) {
        return Err(format!("{metres} metres per CRS unit"));
    }
    let units = match u(0) {
        0 if metres == 1.0 => Units::Degrees,
        1 => Units::Linear(metres),
        2 => Units::WebMercator(metres),
        kind => return Err(format!("unknown georeferencing units {kind} of {metres} m")),
    };
    let (first, cell) = ((f(16), f(24)), (f(32), f(40)));
    let finite = [first.0, first.1, cell.0, cell.1]
        .iter()
        .all(|v| v.is_finite() && v.abs() <= MAX_COORDINATE);
    if !finite || cell.0 <= 0.0 || cell.1 <= 0.0 {
        return Err(format!(
            "georeferencing of sample (0, 0) at {first:?} with cells of {cell:?}: each must be \
             finite and within {MAX_COORDINATE}, the cells positive"
        ));
    }
    let crs = std::str::from_utf8(&bytes[48..48 + n])
        .map_err(|_| "the CRS's name is not UTF-8".to_string())?
        .to_string();
    Ok(Georef {
        crs,
        units,
        first,
        cell,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_unit_reads_back_exactly() {
        for units in [
            Units::Degrees,
            Units::Linear(0.3048),
            Units::WebMercator(1.0),
        ] {
            let g = Georef {
                crs: "EPSG:32610 «x»".into(),
                units,
                first: (512_345.678_9, 5_234_567.125),
                cell: (0.1 + 0.2, 30.0),
            };
            let b = to_bytes(&g);
            assert_eq!(b.len(), len(&g));
            assert_eq!(parse(&b), Ok(g));
        }
    }

    #[test]
    fn a_long_name_is_cut_on_a_character() {
        let g = Georef {
            crs: "é".repeat(MAX_CRS_NAME),
            units: Units::Degrees,
            first: (0.0, 0.0),
            cell: (1.0, 1.0),
        };
        let b = to_bytes(&g);
        assert_eq!(b.len(), MAX_LEN);
        assert_eq!(parse(&b).unwrap().crs, "é".repeat(MAX_CRS_NAME / 2));
    }

    #[test]
    fn bad_blocks_say_what_is_wrong() {
        let g = Georef {
            crs: "EPSG:4326".into(),
            units: Units::Degrees,
            first: (7.0, 47.0),
            cell: (1e-3, 1e-3),
        };
        let good = to_bytes(&g);
        let resealed = |edit: &dyn Fn(&mut Vec<u8>)| {
            let mut b = good.clone();
            edit(&mut b);
            let end = b.len() - 4;
            let crc = crc32fast::hash(&b[..end]);
            b[end..].copy_from_slice(&crc.to_le_bytes());
            parse(&b).unwrap_err()
        };
        assert!(parse(&good[..20]).unwrap_err().contains("20 bytes"));
        let mut flipped = good.clone();
        flipped[17] ^= 1;
        assert!(parse(&flipped).unwrap_err().contains("checksum"));
        assert!(resealed(&|b| b[0] = 9).contains("units 9"));
        assert!(resealed(&|b| b[4] = 3).contains("CRS name of 3 bytes"));
        assert!(resealed(&|b| b[32..40].copy_from_slice(&(-1f64).to_le_bytes())).contains("cells"));
        assert!(resealed(&|b| b[48] = 0xff).contains("UTF-8"));
    }
}
