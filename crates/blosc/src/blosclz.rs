//! BloscLZ stream decoder (codec 0 of the blosc header), written from the
//! format description; c-blosc has no separate specification of it.
//!
//! Why this file exists: BloscLZ is c-blosc's default codec and no Rust crate
//! decodes it.
//!
//! # Stream layout
//!
//! A stream is a sequence of tokens; the first byte's top 3 bits are a marker
//! and are ignored, so the first token is always a literal run.  For each
//! control byte `c`:
//!
//! * `c < 32`: literal run of `c + 1` bytes, copied from the input.
//! * `c >= 32`: match.  `len = (c >> 5) - 1`; when that is 6, extension bytes
//!   follow, each added to `len`, until one is not 255.  Then one byte `code`:
//!   `len += 3`, `distance = ((c & 31) << 8) + code`.  When `code == 255` and
//!   `c & 31 == 31`, two more bytes hold a big-endian `d16` and
//!   `distance = d16 + 8191` (far match).  The match copies `len` bytes from
//!   `distance + 1` bytes back in the output (overlap allowed: runs repeat).
//!
//! The next control byte follows each token; the stream ends when the input
//! is exhausted.  Like c-blosc, a match that is the very last token is not
//! applied (c-blosc's encoder always ends with a literal run), and every size
//! and back-reference is checked against the buffers.

/// Far-match distance bias.
const MAX_DISTANCE: usize = 8191;

/// Decodes `input` into `out`, which must be filled exactly.
pub(crate) fn decompress(input: &[u8], out: &mut [u8]) -> Result<(), String> {
    let n = input.len();
    if n == 0 {
        return Err("empty blosclz stream".into());
    }
    let cap = out.len();
    let mut ip = 1usize;
    let mut op = 0usize;
    let mut ctrl = (input[0] & 31) as usize;

    loop {
        if ctrl >= 32 {
            let mut len = (ctrl >> 5) - 1;
            let hi = (ctrl & 31) << 8;
            if len == 6 {
                loop {
                    if ip + 1 >= n {
                        return Err(format!("match length runs past the input at {ip}"));
                    }
                    let code = input[ip];
                    ip += 1;
                    len = len.saturating_add(code as usize);
                    if code != 255 {
                        break;
                    }
                }
            } else if ip + 1 >= n {
                return Err(format!("match distance runs past the input at {ip}"));
            }
            let code = input[ip] as usize;
            ip += 1;
            len = len.saturating_add(3);
            let mut distance = hi + code;
            if code == 255 && hi == 31 << 8 {
                if ip + 1 >= n {
                    return Err(format!("far match distance runs past the input at {ip}"));
                }
                distance = ((input[ip] as usize) << 8 | input[ip + 1] as usize) + MAX_DISTANCE;
                ip += 2;
            }
            if len > cap - op {
                return Err(format!(
                    "match of {len} bytes at output {op} overflows the {cap}-byte block"
                ));
            }
            if distance + 1 > op {
                return Err(format!(
                    "match distance {} at output {op} points before the block start",
                    distance + 1
                ));
            }
            if ip >= n {
                break;
            }
            ctrl = input[ip] as usize;
            ip += 1;
            copy_match(out, op, distance + 1, len);
            op += len;
        } else {
            let run = ctrl + 1;
            if run > cap - op {
                return Err(format!(
                    "literal run of {run} bytes at output {op} overflows the {cap}-byte block"
                ));
            }
            if run > n - ip {
                return Err(format!(
                    "literal run of {run} bytes at input {ip} runs past the {n}-byte stream"
                ));
            }
            out[op..op + run].copy_from_slice(&input[ip..ip + run]);
            op += run;
            ip += run;
            if ip >= n {
                break;
            }
            ctrl = input[ip] as usize;
            ip += 1;
        }
    }
    if op != cap {
        return Err(format!("stream decoded to {op} bytes"));
    }
    Ok(())
}

/// Copies `len` bytes from `dist` bytes back, with LZ77 overlap semantics.
/// The caller has checked `dist <= op` and `op + len <= out.len()`.
#[inline]
fn copy_match(out: &mut [u8], op: usize, dist: usize, len: usize) {
    let from = op - dist;
    if dist == 1 {
        let b = out[from];
        out[op..op + len].fill(b);
    } else if dist >= len {
        out.copy_within(from..from + len, op);
    } else {
        // The pattern of period `dist` doubles with every copy.
        let mut done = 0;
        while done < len {
            let chunk = (op + done - from).min(len - done);
            out.copy_within(from..from + chunk, op + done);
            done += chunk;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn literal_then_run() {
        // literal "ab" (ctrl 1), then match len 3+1=4 at distance 2: c = (2<<5)|0, code 1.
        let input = [1u8, b'a', b'b', 2 << 5, 1, 0, b'z'];
        let mut out = [0u8; 7];
        decompress(&input, &mut out).unwrap();
        assert_eq!(&out, b"abababz");
    }

    #[test]
    fn rejects_reference_before_start() {
        let input = [0u8, b'a', 2 << 5, 5, 0, b'z'];
        let mut out = [0u8; 6];
        assert!(decompress(&input, &mut out).is_err());
    }
}
