//! Reading cells: the csv crate's errors and header look-up as the crate's own, and the one-pass
//! byte reader of the common trials CSV (no quotes): [`read_unquoted`] finds the separators
//! eight bytes at a time and hands each record's fields, as [`Field`]s, to a [`Records`].
//! [`ShortNames`] finds a condition name of up to eight bytes without hashing.

use crate::error::{AnalysisError, Result};

pub(crate) fn csv_error(source_name: &str, error: csv::Error) -> AnalysisError {
    let line = error.position().map(|p| p.line()).unwrap_or(0);
    let message = match error.kind() {
        csv::ErrorKind::UnequalLengths { expected_len, len, .. } => {
            format!("the row has {len} fields but the header has {expected_len}")
        }
        csv::ErrorKind::Utf8 { .. } => "the text is not valid UTF-8".to_string(),
        _ => error.to_string(),
    };
    AnalysisError::MalformedCsv { source_name: source_name.to_string(), line, message }
}

pub(crate) fn header_index(source_name: &str, headers: &csv::StringRecord, column: &str) -> Result<usize> {
    headers.iter().position(|h| h.trim() == column).ok_or_else(|| AnalysisError::MissingColumn {
        source_name: source_name.to_string(),
        column: column.to_string(),
        found: headers.iter().map(|h| h.trim()).collect::<Vec<_>>().join(", "),
    })
}

pub(crate) fn reader(text: &str) -> csv::Reader<&[u8]> {
    csv::ReaderBuilder::new().has_headers(true).flexible(false).from_reader(text.as_bytes())
}

/// A `true`/`false` cell (ASCII case ignored, as spreadsheets write `TRUE`).
#[inline]
pub(super) fn parse_flag(cell: Field) -> Option<bool> {
    const FALSE: u64 = u64::from_le_bytes(*b"false\0\0\0");
    const TRUE: u64 = u64::from_le_bytes(*b"true\0\0\0\0");
    match (cell.text.len(), cell.word) {
        (5, FALSE) => Some(false),
        (4, TRUE) => Some(true),
        _ if cell.text.eq_ignore_ascii_case("true") => Some(true),
        _ if cell.text.eq_ignore_ascii_case("false") => Some(false),
        _ => None,
    }
}

/// What [`read_unquoted`] hands the records it reads to.
pub(super) trait Records {
    /// Room for about `additional` more records.
    fn reserve(&mut self, additional: usize);
    /// One record on line `line`; `field(k)` is its k-th field, trimmed.
    fn record<'f>(&mut self, line: u64, field: impl Fn(usize) -> Field<'f>) -> Result<()>;
}

/// A field of a record, trimmed, with its bytes as one integer where it has at most eight
/// (for comparisons without a loop or a call).
#[derive(Clone, Copy)]
pub(super) struct Field<'f> {
    pub(super) text: &'f str,
    /// [`short_word`] of `text` where it has at most eight bytes, else 0.
    pub(super) word: u64,
}

impl<'f> Field<'f> {
    pub(super) fn new(text: &'f str) -> Field<'f> {
        let word = if text.len() <= 8 { short_word(text.as_bytes()) } else { 0 };
        Field { text, word }
    }

    /// Field `data[start..end]`, trimmed. Where it has at most eight bytes, its word is read
    /// as one load of the eight bytes at `start` (masked to its length) when the text goes on
    /// that far.
    #[inline]
    fn at(data: &'f str, start: usize, end: usize) -> Field<'f> {
        let bytes = data.as_bytes();
        let printable = |byte: u8| (b'!'..=b'~').contains(&byte);
        if !(end > start && printable(bytes[start]) && printable(bytes[end - 1])) {
            return Field::new(data[start..end].trim());
        }
        let length = end - start;
        let word = match bytes.get(start..start + 8) {
            Some(eight) if length <= 8 => {
                u64::from_le_bytes(eight.try_into().expect("eight bytes")) & (u64::MAX >> (64 - 8 * length))
            }
            _ if length <= 8 => short_word(&bytes[start..end]),
            _ => 0,
        };
        Field { text: &data[start..end], word }
    }

    #[inline]
    pub(super) fn is_short(&self) -> bool {
        self.text.len() <= 8
    }

    /// Whether the two fields have the same text.
    #[inline]
    pub(super) fn same(&self, other: Field) -> bool {
        self.text.len() == other.text.len()
            && if self.is_short() { self.word == other.word } else { self.text == other.text }
    }
}

/// Reads the records of `data` (the text after the header, whose first line is `first_line`)
/// in one pass over its bytes: the separators (`,` and `\n`) are found eight bytes at a time
/// ([`Separators`]), each field is a slice of `data` (validated as UTF-8 once, as a whole), and
/// only the columns the analysis reads are looked at. The whole reading where the file has no
/// quote and no `\r` but before a `\n`; returns `Ok(false)` where it has (the caller then reads
/// the file with the csv crate instead). Empty lines are skipped (and not counted in line
/// numbers) and rows of the wrong length refused, all as the csv crate does.
pub(super) fn read_unquoted(
    data: &str,
    source_name: &str,
    first_line: u64,
    n_columns: usize,
    rows: &mut impl Records,
) -> Result<bool> {
    let bytes = data.as_bytes();
    // One search for either; where a `\r` comes first, the rest is checked more closely.
    let crlf = match memchr::memchr2(b'"', b'\r', bytes) {
        None => false,
        Some(at) if bytes[at] == b'"' => return Ok(false),
        Some(at) => {
            if memchr::memchr(b'"', &bytes[at..]).is_some()
                || !memchr::memchr_iter(b'\r', &bytes[at..]).all(|k| bytes.get(at + k + 1) == Some(&b'\n'))
            {
                return Ok(false);
            }
            true
        }
    };
    // Room for every row, from the length of the first.
    let first_length = memchr::memchr(b'\n', bytes).unwrap_or(bytes.len()) + 1;
    rows.reserve(bytes.len() / first_length.max(8) + 1);
    // starts[k]: where field k of the line begins; field k ends one byte before starts[k + 1].
    let mut starts = vec![0usize; n_columns + 1];
    let mut line_number = first_line;
    let mut line_end = |line_start: usize, end: usize, n_fields: usize, starts: &mut [usize]| -> Result<()> {
        // Empty lines are skipped and, as the csv crate counts, not counted.
        if end > line_start {
            if n_fields != n_columns {
                return Err(AnalysisError::MalformedCsv {
                    source_name: source_name.to_string(),
                    line: line_number,
                    message: format!("the row has {n_fields} fields but the header has {n_columns}"),
                });
            }
            starts[0] = line_start;
            starts[n_columns] = end + 1;
            rows.record(line_number, |k| Field::at(data, starts[k], starts[k + 1] - 1))?;
            line_number += 1;
        }
        Ok(())
    };
    let mut separators = Separators::new(bytes);
    let mut line_start = 0;
    loop {
        // A line as expected has n_columns − 1 commas, then a `\n` (or the end of the text):
        // the loop over them ends where the count says, with few mispredicted branches.
        let mut n_fields = 1;
        let mut next = separators.next();
        while n_fields < n_columns {
            match next {
                Some((at, false)) => {
                    starts[n_fields] = at + 1;
                    n_fields += 1;
                    next = separators.next();
                }
                _ => break,
            }
        }
        // Fields beyond the header's, counted for the error.
        while let Some((_, false)) = next {
            n_fields += 1;
            next = separators.next();
        }
        let end = match next {
            Some((at, _)) => at,
            None if line_start < bytes.len() => bytes.len(),
            None => break,
        };
        let content_end = if crlf && end > line_start && bytes[end - 1] == b'\r' { end - 1 } else { end };
        line_end(line_start, content_end, n_fields, &mut starts)?;
        if next.is_none() {
            break;
        }
        line_start = end + 1;
    }
    Ok(true)
}

/// The positions of `,` and `\n` in a text, in order, each with whether it is a `\n`. Sixty-four
/// bytes at a time become one bit mask (eight bytes tested at once as one integer: a byte
/// equal to a separator becomes zero after an exclusive or, and zero bytes are found exactly
/// by Mycroft's test; a multiplication gathers their high bits), so the cost is a few
/// operations per eight bytes and a bit scan and a byte read per separator.
struct Separators<'a> {
    bytes: &'a [u8],
    /// Where the current block starts.
    base: usize,
    /// Bit k: byte `base + k` is a `,` or `\n` (found, not yet returned).
    separators: u64,
}

impl<'a> Separators<'a> {
    const BLOCK: usize = 64;

    fn new(bytes: &'a [u8]) -> Separators<'a> {
        let mut separators = Separators { bytes, base: 0, separators: 0 };
        separators.load();
        separators
    }

    /// The high bit of every byte of `word` that equals `byte`.
    #[inline]
    fn equal(word: u64, byte: u8) -> u64 {
        const LOW: u64 = 0x7f7f_7f7f_7f7f_7f7f;
        let x = word ^ (0x0101_0101_0101_0101 * u64::from(byte));
        !(((x & LOW) + LOW) | x | LOW)
    }

    /// Byte k's high bit (of a mask with only high bits set) as bit k.
    #[inline]
    fn gather(high_bits: u64) -> u64 {
        (high_bits >> 7).wrapping_mul(0x0102_0408_1020_4080) >> 56
    }

    #[inline]
    fn load(&mut self) {
        let mut separators = 0;
        match self.bytes.get(self.base..self.base + Self::BLOCK) {
            Some(block) => {
                for (k, chunk) in block.chunks_exact(8).enumerate() {
                    let word = u64::from_le_bytes(chunk.try_into().expect("eight bytes"));
                    separators |= Self::gather(Self::equal(word, b'\n') | Self::equal(word, b',')) << (8 * k);
                }
            }
            None => {
                for (k, &byte) in self.bytes[self.base.min(self.bytes.len())..].iter().enumerate() {
                    separators |= u64::from(byte == b'\n' || byte == b',') << k;
                }
            }
        }
        self.separators = separators;
    }
}

impl Iterator for Separators<'_> {
    type Item = (usize, bool);

    #[inline]
    fn next(&mut self) -> Option<(usize, bool)> {
        while self.separators == 0 {
            self.base += Self::BLOCK;
            if self.base >= self.bytes.len() {
                return None;
            }
            self.load();
        }
        let bit = self.separators.trailing_zeros();
        self.separators &= self.separators - 1;
        let at = self.base + bit as usize;
        Some((at, self.bytes[at] == b'\n'))
    }
}

/// A name of up to eight bytes as an integer (little-endian, zero-padded). With the length, it
/// tells any two such names apart.
/// Built from two overlapping loads (no copy through memory, which would stall the load after it).
#[inline]
pub(super) fn short_word(name: &[u8]) -> u64 {
    let length = name.len();
    debug_assert!(length <= 8);
    if length >= 4 {
        let low = u32::from_le_bytes(name[..4].try_into().expect("four bytes"));
        let high = u32::from_le_bytes(name[length - 4..length].try_into().expect("four bytes"));
        u64::from(low) | u64::from(high) << (8 * (length - 4))
    } else if length > 0 {
        let byte = |k: usize| u64::from(name[k]) << (8 * k);
        byte(0) | byte(length / 2) | byte(length - 1)
    } else {
        0
    }
}

/// A perfect hash of the condition names of up to eight bytes: slot
/// `((word + length) · multiplier) >> shift` of a table four times as long as the names holds
/// the name's word, length and index, and no two names share a slot (a multiplier is searched
/// for when the table is built: a few tries for a study's handful of conditions). `complete` is
/// false where there are more than [`ShortNames::MAX_NAMES`] short names or no multiplier was
/// found; then every name goes through the hash map.
pub(super) struct ShortNames {
    multiplier: u64,
    shift: u32,
    /// `(word, length, index)`; an empty slot has length `u32::MAX`.
    slots: Vec<(u64, u32, u32)>,
    pub(super) complete: bool,
}

impl ShortNames {
    /// Odd constants (SplitMix64 outputs) tried in turn as the multiplier.
    const TRIES: usize = 64;
    const MAX_NAMES: usize = 32;

    pub(super) fn new(names: &[String]) -> ShortNames {
        let short: Vec<(u64, u32, u32)> = names
            .iter()
            .enumerate()
            .filter(|(_, name)| name.len() <= 8)
            .map(|(k, name)| (short_word(name.as_bytes()), name.len() as u32, k as u32))
            .collect();
        let bits = (4 * short.len()).next_power_of_two().max(4).trailing_zeros();
        let shift = 64 - bits;
        if short.len() > Self::MAX_NAMES {
            return ShortNames { multiplier: 1, shift, slots: Vec::new(), complete: false };
        }
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..Self::TRIES {
            state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            let multiplier = (z ^ (z >> 31)) | 1;
            let mut slots = vec![(0, u32::MAX, 0); 1 << bits];
            let placed = short.iter().all(|&(word, length, index)| {
                let slot = &mut slots[Self::slot(word, length, multiplier, shift)];
                let free = slot.1 == u32::MAX;
                *slot = (word, length, index);
                free
            });
            if placed {
                return ShortNames { multiplier, shift, slots, complete: true };
            }
        }
        ShortNames { multiplier: 1, shift, slots: Vec::new(), complete: false }
    }

    #[inline]
    fn slot(word: u64, length: u32, multiplier: u64, shift: u32) -> usize {
        (word.wrapping_add(u64::from(length)).wrapping_mul(multiplier) >> shift) as usize
    }

    /// The index of a name of up to eight bytes, if it is a known condition.
    #[inline]
    pub(super) fn find(&self, name: Field) -> Option<u32> {
        let (word, length) = (name.word, name.text.len() as u32);
        let (slot_word, slot_length, index) = self.slots[Self::slot(word, length, self.multiplier, self.shift)];
        (slot_word == word && slot_length == length).then_some(index)
    }
}

/// The column names of a CSV text's header line (trimmed, quotes removed), to tell one kind of
/// file from another before it is read (a task CSV, a threshold export).
pub fn header_columns(text: &str) -> Vec<&str> {
    let header = text.lines().next().unwrap_or("");
    header.split(',').map(|c| c.trim().trim_matches('"')).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The separators found a block at a time are those a byte-by-byte scan finds, for every
    /// byte value and text length (blocks and their tails).
    #[test]
    fn separators_are_those_a_byte_scan_finds() {
        let bytes: Vec<u8> = (0..300u32)
            .map(|k| [b',', b'\n', b'a', 0x80 | b',', 0x80 | b'\n', (k * 37) as u8][k as usize % 6])
            .collect();
        for length in 0..bytes.len() {
            let text = &bytes[..length];
            let found: Vec<(usize, bool)> = Separators::new(text).collect();
            let expected: Vec<(usize, bool)> = text
                .iter()
                .enumerate()
                .filter(|&(_, &b)| b == b',' || b == b'\n')
                .map(|(k, &b)| (k, b == b'\n'))
                .collect();
            assert_eq!(found, expected, "length {length}");
        }
    }

    #[test]
    fn short_names_find_every_condition_and_nothing_else() {
        let names: Vec<String> =
            ["LQ", "GI", "CM", "GI+CM", "CA", "GI+CA", "CM+CA", "HQ", "", "A\0"].map(String::from).to_vec();
        let table = ShortNames::new(&names);
        assert!(table.complete);
        for (k, name) in names.iter().enumerate() {
            assert_eq!(table.find(Field::new(name)), Some(k as u32), "{name:?}");
        }
        for other in ["A", "HQ ", "GI+C", "CM+CA+", "lq"] {
            assert_eq!(table.find(Field::new(other)), None, "{other:?}");
        }
        let many: Vec<String> = (0..40).map(|k| format!("C{k}")).collect();
        assert!(!ShortNames::new(&many).complete, "more than MAX_NAMES go through the hash map");
    }
}
