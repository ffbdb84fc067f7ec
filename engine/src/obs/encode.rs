//! The encoders: they write the symbol screen, status planes and the history plane into a
//! caller-provided buffer.

use super::spec::{Encoding, ObsBufMut, ObsError, ObsSpec};
use super::status::Status;

/// What an encoder reads: the symbol screen, the ascii screen, the visited plane and status.
pub(crate) struct ObsSource<'a> {
    pub height: usize,
    pub width: usize,
    pub symbols: usize,
    pub sym: &'a [u8],
    pub ascii: &'a [u8],
    pub visited: &'a [u8],
    pub status: Status,
    pub amulet_level: u32,
}

/// Extra planes after the map planes: status planes then history.
fn extra_planes(spec: &ObsSpec) -> usize {
    spec.status.count() + usize::from(spec.history)
}

/// The observation shape for `spec` on an `height` x `width` screen with `symbols` symbols.
pub(crate) fn shape(spec: &ObsSpec, height: usize, width: usize, symbols: usize) -> Vec<usize> {
    let extra = extra_planes(spec);
    match spec.encoding {
        Encoding::SymbolOnehot => vec![symbols + extra, height, width],
        Encoding::Gray => vec![1 + extra, height, width],
        Encoding::SymbolIndex | Encoding::Ascii => {
            if extra == 0 {
                vec![height, width]
            } else {
                vec![1 + extra, height, width]
            }
        }
        Encoding::StatusVector => {
            vec![if spec.status.count() == 0 {
                9
            } else {
                spec.status.count()
            }]
        }
    }
}

/// Writes the observation. Checks dtype and length first; never panics.
pub(crate) fn write(
    spec: &ObsSpec,
    src: &ObsSource<'_>,
    out: ObsBufMut<'_>,
) -> Result<(), ObsError> {
    let shape = shape(spec, src.height, src.width, src.symbols);
    let expected: usize = shape.iter().product();
    if out.dtype() != spec.dtype {
        return Err(ObsError::WrongDtype {
            expected: spec.dtype,
            got: out.dtype(),
        });
    }
    if out.len() != expected {
        return Err(ObsError::WrongLength {
            expected,
            got: out.len(),
            shape,
        });
    }
    let hw = src.height * src.width;
    let status_vals = selected_status(spec, src);
    match out {
        ObsBufMut::U8(buf) => {
            let map_planes = match spec.encoding {
                Encoding::SymbolOnehot => {
                    for (c, plane) in buf.chunks_exact_mut(hw).take(src.symbols).enumerate() {
                        let c = c as u8;
                        for (o, &s) in plane.iter_mut().zip(src.sym) {
                            *o = u8::from(s == c);
                        }
                    }
                    src.symbols
                }
                Encoding::SymbolIndex => {
                    buf[..hw].copy_from_slice(src.sym);
                    1
                }
                Encoding::Ascii => {
                    buf[..hw].copy_from_slice(src.ascii);
                    1
                }
                Encoding::Gray => {
                    let n = src.symbols as u32;
                    for (o, &s) in buf[..hw].iter_mut().zip(src.sym) {
                        *o = (u32::from(s) * 255 / n) as u8;
                    }
                    1
                }
                Encoding::StatusVector => {
                    for (o, v) in buf.iter_mut().zip(status_vals.iter()) {
                        *o = if spec.normalize_status {
                            (v * 255.0).round() as u8
                        } else {
                            v.clamp(0.0, 255.0) as u8
                        };
                    }
                    return Ok(());
                }
            };
            let mut planes = buf[map_planes * hw..].chunks_exact_mut(hw);
            for v in status_vals.iter() {
                let b = if spec.normalize_status {
                    (v * 255.0).round() as u8
                } else {
                    v.clamp(0.0, 255.0) as u8
                };
                if let Some(p) = planes.next() {
                    p.fill(b);
                }
            }
            if spec.history
                && let Some(p) = planes.next()
            {
                p.copy_from_slice(src.visited);
            }
        }
        ObsBufMut::F32(buf) => {
            let map_planes = match spec.encoding {
                Encoding::SymbolOnehot => {
                    for (c, plane) in buf.chunks_exact_mut(hw).take(src.symbols).enumerate() {
                        let c = c as u8;
                        for (o, &s) in plane.iter_mut().zip(src.sym) {
                            *o = if s == c { 1.0 } else { 0.0 };
                        }
                    }
                    src.symbols
                }
                Encoding::SymbolIndex => {
                    for (o, &s) in buf[..hw].iter_mut().zip(src.sym) {
                        *o = f32::from(s);
                    }
                    1
                }
                Encoding::Ascii => {
                    for (o, &s) in buf[..hw].iter_mut().zip(src.ascii) {
                        *o = f32::from(s);
                    }
                    1
                }
                Encoding::Gray => {
                    let n = src.symbols as f32;
                    for (o, &s) in buf[..hw].iter_mut().zip(src.sym) {
                        *o = f32::from(s) / n;
                    }
                    1
                }
                Encoding::StatusVector => {
                    for (o, v) in buf.iter_mut().zip(status_vals.iter()) {
                        *o = *v;
                    }
                    return Ok(());
                }
            };
            let mut planes = buf[map_planes * hw..].chunks_exact_mut(hw);
            for v in status_vals.iter() {
                if let Some(p) = planes.next() {
                    p.fill(*v);
                }
            }
            if spec.history
                && let Some(p) = planes.next()
            {
                for (o, &s) in p.iter_mut().zip(src.visited) {
                    *o = f32::from(s);
                }
            }
        }
    }
    Ok(())
}

/// The selected status values (as f32, raw or normalised), in flag order. For
/// `StatusVector` with empty flags, all 9.
fn selected_status(spec: &ObsSpec, src: &ObsSource<'_>) -> StatusBuf {
    let mut flags = spec.status.0 & 511;
    if spec.encoding == Encoding::StatusVector && flags == 0 {
        flags = 511;
    }
    let mut out = StatusBuf {
        vals: [0.0; 9],
        len: 0,
    };
    if flags == 0 {
        return out;
    }
    let raw = src.status.values();
    let norm = src.status.normalized(src.amulet_level);
    for bit in 0..9 {
        if flags & (1 << bit) != 0 {
            out.vals[out.len] = if spec.normalize_status {
                norm[bit]
            } else {
                raw[bit] as f32
            };
            out.len += 1;
        }
    }
    out
}

/// Up to 9 status values, no allocation.
struct StatusBuf {
    vals: [f32; 9],
    len: usize,
}

impl StatusBuf {
    fn iter(&self) -> std::slice::Iter<'_, f32> {
        self.vals[..self.len].iter()
    }
}
