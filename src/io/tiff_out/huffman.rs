//! Deflate's fastest useful form for predicted image rows: one dynamic
//! block of Huffman codes fitted to the tile's bytes, with no search for
//! matches but runs of zeros (a tile's fill) as matches at distance 1.
//! Rows after the horizontal predictor hardly repeat, so matches gain
//! little (docs/BENCHMARKS.md): a code a byte is nearly as tight as
//! libdeflate's fastest level, and several times as fast.

/// Longest literal code: four codes (56 bits) and the fewer than 8 bits
/// held fit one u64.
const MAX_LEN: u8 = 14;
/// The length symbol of a 258-byte match, the longest.
const RUN_SYMBOL: usize = 285;
const RUN: usize = 258;
/// Literal/length symbols: bytes, end of block, lengths up to 258.
const SYMBOLS: usize = 286;
const END: usize = 256;
/// The order the code-length code's lengths take in the header (RFC 1951
/// 3.2.7).
const CL_ORDER: [usize; 19] = [16, 17, 18, 0, 8, 7, 9, 6, 10, 5, 11, 4, 12, 3, 13, 2, 14, 1, 15];

/// `data` as a zlib stream (deflate with the Adler-32 check, as TIFF's
/// compression 8 holds it); `None` where it might come out larger than
/// `data` (or `data` holds more bytes than a count of them does).
pub fn zlib(data: &[u8]) -> Option<Vec<u8>> {
    if data.len() >= u32::MAX as usize {
        return None;
    }
    let runs = zero_runs(data);
    let freqs = symbol_counts(data, &runs);
    let lengths = code_lengths(&freqs, MAX_LEN);
    let codes = canonical(&lengths);
    // The stream's size is known before it is written: at most the
    // header's 2 + 262 bytes, the codes, the last byte and the check.
    let body_bits: u64 = freqs.iter().zip(&lengths).map(|(&f, &l)| f as u64 * l as u64).sum::<u64>() + freqs[RUN_SYMBOL] as u64;
    let size = 2 + 262 + body_bits.div_ceil(8) as usize + 1 + 4;
    if size > data.len() {
        return None;
    }
    // 8 bytes spare: each write puts a whole word.
    let mut bits = Bits { out: vec![0; size + 8], pos: 2, buf: 0, n: 0 };
    bits.out[..2].copy_from_slice(&[0x78, 0x01]);
    block_header(&mut bits, &lengths);
    // Each byte's code and length in one word.
    let table: [u32; 256] = std::array::from_fn(|s| codes[s] as u32 | (lengths[s] as u32) << 16);
    // A match: its length's code, then distance code 0 (one bit, 0).
    let (run_code, run_len) = (codes[RUN_SYMBOL] as u64, lengths[RUN_SYMBOL] as u32 + 1);
    let mut start = 0;
    for &(a, n) in &runs {
        bits.put_bytes(&data[start..a], &table);
        // The run's first zero, then its matches.
        bits.put_bytes(&[0], &table);
        for _ in 0..n {
            bits.put(run_code, run_len);
        }
        start = a + 1 + n * RUN;
    }
    bits.put_bytes(&data[start..], &table);
    bits.put(codes[END] as u64, lengths[END] as u32);
    let mut out = bits.finish();
    out.extend_from_slice(&libdeflater::adler32(data).to_be_bytes());
    Some(out)
}

/// How often each literal/length symbol comes: the bytes outside the runs
/// (each run's first zero among them), the runs' matches, one end.
fn symbol_counts(data: &[u8], runs: &[(usize, usize)]) -> [u32; SYMBOLS] {
    // Four histograms in turn, so that equal bytes in a row do not wait
    // on one another's count.
    let mut hist = [[0u32; 256]; 4];
    let mut count = |bytes: &[u8]| {
        let mut quads = bytes.chunks_exact(4);
        for q in &mut quads {
            hist[0][q[0] as usize] += 1;
            hist[1][q[1] as usize] += 1;
            hist[2][q[2] as usize] += 1;
            hist[3][q[3] as usize] += 1;
        }
        for &x in quads.remainder() {
            hist[0][x as usize] += 1;
        }
    };
    let mut start = 0;
    let mut matches = 0;
    for &(a, n) in runs {
        count(&data[start..=a]);
        matches += n as u32;
        start = a + 1 + n * RUN;
    }
    count(&data[start..]);
    let mut freqs = [0u32; SYMBOLS];
    for (s, f) in freqs.iter_mut().take(256).enumerate() {
        *f = hist[0][s] + hist[1][s] + hist[2][s] + hist[3][s];
    }
    freqs[END] = 1;
    freqs[RUN_SYMBOL] = matches;
    freqs
}

/// Where `data` has runs of zeros long enough for a match: each run's
/// first byte and its count of whole 258-byte matches after it.
fn zero_runs(data: &[u8]) -> Vec<(usize, usize)> {
    // A run of 259 or more holds a whole aligned block of 32 zeros: only
    // blocks are looked at, and each run measured from one.
    const B: usize = 32;
    let mut runs = Vec::new();
    let mut from = 0; // the end of the last run
    let mut k = 0;
    while k + B <= data.len() {
        if data[k..k + B].iter().fold(0u8, |o, &x| o | x) != 0 {
            k += B;
            continue;
        }
        let mut a = k;
        while a > from && data[a - 1] == 0 {
            a -= 1;
        }
        let mut b = k + B;
        while b < data.len() && data[b] == 0 {
            b += 1;
        }
        let n = (b - a - 1) / RUN;
        from = if n > 0 {
            runs.push((a, n));
            a + 1 + n * RUN
        } else {
            b
        };
        k = b.next_multiple_of(B).max(k + B);
    }
    runs
}

/// The block's header: last block, dynamic codes; all 286 literal/length
/// code lengths and two distance codes of one bit (the first, distance 1,
/// for runs; two, a complete code, as zlib itself sends for old
/// decoders' sake), each length written as itself in the code-length code.
fn block_header(bits: &mut Bits, lengths: &[u8; SYMBOLS]) {
    bits.put(1, 1);
    bits.put(2, 2);
    bits.put((SYMBOLS - 257) as u64, 5);
    bits.put(1, 5);
    let all: Vec<u8> = lengths.iter().copied().chain([1, 1]).collect();
    let mut cl_freqs = [0u32; 19];
    for &l in &all {
        cl_freqs[l as usize] += 1;
    }
    // Two symbols at least: a code of one is incomplete, which inflate
    // refuses for this code.
    if cl_freqs.iter().filter(|&&f| f > 0).count() < 2 {
        cl_freqs[usize::from(cl_freqs[0] > 0)] = 1;
    }
    let cl_lengths = code_lengths(&cl_freqs, 7);
    let cl_codes = canonical(&cl_lengths);
    let hclen = CL_ORDER.iter().rposition(|&s| cl_lengths[s] > 0).map_or(4, |i| (i + 1).max(4));
    bits.put((hclen - 4) as u64, 4);
    for &s in &CL_ORDER[..hclen] {
        bits.put(cl_lengths[s] as u64, 3);
    }
    for &l in &all {
        bits.put(cl_codes[l as usize] as u64, cl_lengths[l as usize] as u32);
    }
}

/// Code lengths of at most `max` bits for `freqs` (unused symbols: 0):
/// Huffman's, then the deepest leaves pulled up until the lengths fit
/// (as miniz and zlib do); the shortest to the most frequent.
fn code_lengths<const N: usize>(freqs: &[u32; N], max: u8) -> [u8; N] {
    let mut syms: Vec<(u32, usize)> = freqs.iter().enumerate().filter(|(_, &f)| f > 0).map(|(s, &f)| (f, s)).collect();
    let mut lengths = [0u8; N];
    if syms.len() < 2 {
        // One symbol (the end alone, or the code-length code's one
        // length): a one-bit code.
        for &(_, s) in &syms {
            lengths[s] = 1;
        }
        return lengths;
    }
    syms.sort_unstable();
    // Huffman's tree by two queues: the leaves, sorted, and the joined
    // nodes, which come out sorted too.
    let n = syms.len();
    let mut weight: Vec<u64> = syms.iter().map(|&(f, _)| f as u64).chain(std::iter::repeat_n(0, n - 1)).collect();
    let mut parent = vec![0usize; 2 * n - 1];
    let (mut leaf, mut node) = (0, n);
    for next in n..2 * n - 1 {
        let mut lightest = || {
            let take_leaf = leaf < n && (node >= next || weight[leaf] <= weight[node]);
            let i = if take_leaf { &mut leaf } else { &mut node };
            *i += 1;
            *i - 1
        };
        let (a, b) = (lightest(), lightest());
        weight[next] = weight[a] + weight[b];
        parent[a] = next;
        parent[b] = next;
    }
    // Depths from the root down: a parent comes after its children.
    let mut depth = vec![0usize; 2 * n - 1];
    for i in (0..2 * n - 2).rev() {
        depth[i] = depth[parent[i]] + 1;
    }
    let max = max as usize;
    let mut count = vec![0u32; max + 1];
    for &d in &depth[..n] {
        count[d.min(max)] += 1;
    }
    // Kraft's sum, in units of the longest code: pull leaves up from the
    // bottom until it is one.
    let mut total: u64 = (1..=max).map(|l| (count[l] as u64) << (max - l)).sum();
    while total > 1 << max {
        count[max] -= 1;
        if let Some(l) = (1..max).rev().find(|&l| count[l] > 0) {
            count[l] -= 1;
            count[l + 1] += 2;
        }
        total -= 1;
    }
    let mut l = 1;
    for &(_, s) in syms.iter().rev() {
        while count[l] == 0 {
            l += 1;
        }
        lengths[s] = l as u8;
        count[l] -= 1;
    }
    lengths
}

/// Canonical codes for `lengths`, their bits reversed (deflate writes a
/// code from its first bit, into the low end of the byte).
fn canonical<const N: usize>(lengths: &[u8; N]) -> [u16; N] {
    let mut count = [0u16; 16];
    for &l in lengths {
        count[l as usize] += 1;
    }
    count[0] = 0;
    let mut next = [0u16; 16];
    let mut code = 0u16;
    for l in 1..16 {
        code = (code + count[l - 1]) << 1;
        next[l] = code;
    }
    std::array::from_fn(|s| {
        let l = lengths[s] as usize;
        if l == 0 {
            return 0;
        }
        next[l] += 1;
        (next[l] - 1).reverse_bits() >> (16 - l)
    })
}

/// Bits on their way out, the first lowest, into a buffer sized for the
/// whole stream and 8 bytes more: fewer than 8 are held between calls, so
/// that up to 56 more fit the word, and each call writes the whole word.
struct Bits {
    out: Vec<u8>,
    pos: usize,
    buf: u64,
    n: u32,
}

impl Bits {
    fn put(&mut self, bits: u64, len: u32) {
        (self.buf, self.n, self.pos) = Self::step(&mut self.out, (self.buf, self.n, self.pos), bits, len);
    }

    #[inline(always)]
    fn step(out: &mut [u8], (buf, n, pos): (u64, u32, usize), bits: u64, len: u32) -> (u64, u32, usize) {
        let buf = buf | bits << n;
        let total = n + len;
        out[pos..pos + 8].copy_from_slice(&buf.to_le_bytes());
        let whole = total >> 3;
        (buf.checked_shr(whole * 8).unwrap_or(0), total & 7, pos + whole as usize)
    }

    /// Each byte's code from `table` (code | length << 16), four bytes a
    /// step, the state held in registers through the loop.
    fn put_bytes(&mut self, bytes: &[u8], table: &[u32; 256]) {
        let mut state = (self.buf, self.n, self.pos);
        let mut quads = bytes.chunks_exact(4);
        for q in &mut quads {
            let e = [table[q[0] as usize], table[q[1] as usize], table[q[2] as usize], table[q[3] as usize]];
            let (l0, l1, l2, l3) = (e[0] >> 16, e[1] >> 16, e[2] >> 16, e[3] >> 16);
            let code = |i: usize| (e[i] & 0xffff) as u64;
            let v = code(0) | code(1) << l0 | code(2) << (l0 + l1) | code(3) << (l0 + l1 + l2);
            state = Self::step(&mut self.out, state, v, l0 + l1 + l2 + l3);
        }
        for &x in quads.remainder() {
            let e = table[x as usize];
            state = Self::step(&mut self.out, state, (e & 0xffff) as u64, e >> 16);
        }
        (self.buf, self.n, self.pos) = state;
    }

    fn finish(mut self) -> Vec<u8> {
        if self.n > 0 {
            self.out[self.pos] = self.buf as u8;
            self.pos += 1;
        }
        self.out.truncate(self.pos);
        self.out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;

    /// Decoded by zlib (through flate2) and by libdeflate: both must give
    /// the bytes back.
    fn round_trip(data: &[u8]) -> usize {
        let z = zlib(data).expect("compressible");
        let mut back = Vec::new();
        flate2::read::ZlibDecoder::new(&z[..]).read_to_end(&mut back).expect("zlib inflates it");
        assert!(back == data, "zlib: {} bytes back of {}", back.len(), data.len());
        let mut out = vec![0u8; data.len()];
        let n = libdeflater::Decompressor::new().zlib_decompress(&z, &mut out).expect("libdeflate inflates it");
        assert!(n == data.len() && out == data, "libdeflate");
        z.len()
    }

    fn noise(seed: u64, n: usize, spread: u64) -> Vec<u8> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                s = s.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
                ((s >> 33) % spread) as u8
            })
            .collect()
    }

    #[test]
    fn predicted_rows_come_back_and_shrink_to_their_entropy() {
        // Differences in -4..4: 3.17 bits of entropy a byte.
        let data: Vec<u8> = noise(7, 196_608, 9).into_iter().map(|v| v.wrapping_sub(4)).collect();
        let z = round_trip(&data);
        // Huffman's best for nine near-equal counts and the end: 3.33 bits.
        assert!(z * 8 < data.len() * 334 / 100, "{z} bytes for {}", data.len());
    }

    #[test]
    fn runs_of_zeros_become_matches_and_every_edge_case_comes_back() {
        // A fill tile (a few hundred bytes, not a bit a byte), a run at
        // either end, runs one short of, at and just past a match, no
        // bytes, one byte, one value only.
        let zero = vec![0u8; 196_608];
        assert!(round_trip(&zero) < 400);
        let mut islands = zero.clone();
        islands[1000] = 7;
        islands[50_000..50_100].fill(3);
        *islands.last_mut().unwrap() = 9;
        assert!(round_trip(&islands) < 800);
        for run in [257, 258, 259, 260, 517, 518, 1000] {
            for lead in [0, 1, 31, 33] {
                let mut d = noise(run as u64, 3000, 16);
                d.iter_mut().for_each(|x| *x |= 1);
                d.splice(lead..lead, std::iter::repeat_n(0, run));
                round_trip(&d);
            }
        }
        // Too short for the header to pay: left to another coder.
        assert!(zlib(&[]).is_none() && zlib(&[5]).is_none());
        round_trip(&[200; 5000]);
    }

    #[test]
    fn skewed_counts_are_held_to_the_longest_code() {
        // Fibonacci counts would give codes far past 14 bits; limited,
        // they still decode.
        let mut data = Vec::new();
        let (mut a, mut b) = (1usize, 1usize);
        for s in 1..=25u8 {
            data.extend(std::iter::repeat_n(s, a));
            (a, b) = (b, a + b);
        }
        let freqs = symbol_counts(&data, &zero_runs(&data));
        let lengths = code_lengths(&freqs, MAX_LEN);
        assert!(*lengths.iter().max().unwrap() <= MAX_LEN, "{lengths:?}");
        let kraft: f64 = lengths.iter().filter(|&&l| l > 0).map(|&l| 0.5f64.powi(l as i32)).sum();
        assert_eq!(kraft, 1.0, "a complete code");
        round_trip(&data);
    }

    #[test]
    fn bytes_that_do_not_compress_are_left_to_another_coder() {
        assert!(zlib(&noise(3, 100_000, 256)).is_none());
    }
}
