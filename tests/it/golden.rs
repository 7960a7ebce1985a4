//! Golden digests: every computed dataset of a result file as FNV-1a 64
//! over its bytes, the rule of `tests/golden/dump_digests.py`, which wrote
//! the golden files from earlier binaries' results.

/// FNV-1a 64 over bytes: the digest of `tests/golden/dump_digests.py`.
fn fnv1a(bytes: impl IntoIterator<Item = u8>) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bytes {
        h = (h ^ b as u64).wrapping_mul(0x0100_0000_01b3);
    }
    h
}

/// Every numeric dataset under `group`, as (path, element count, digest of
/// its little-endian bytes in row-major order).
pub fn digests(group: &hdf5::Group, prefix: &str, out: &mut Vec<(String, usize, u64)>) {
    use hdf5::types::{FloatSize, IntSize, TypeDescriptor as T};
    let mut names = group.member_names().unwrap();
    names.sort();
    for name in names {
        let path = format!("{prefix}/{name}");
        if let Ok(sub) = group.group(&name) {
            digests(&sub, &path, out);
            continue;
        }
        let ds = group.dataset(&name).unwrap();
        let le = |bytes: Vec<Vec<u8>>| bytes.into_iter().flatten();
        let (n, h) = match ds.dtype().unwrap().to_descriptor().unwrap() {
            T::Float(FloatSize::U8) => {
                let v = ds.read_raw::<f64>().unwrap();
                (
                    v.len(),
                    fnv1a(le(v.iter().map(|x| x.to_le_bytes().to_vec()).collect())),
                )
            }
            T::Float(FloatSize::U4) => {
                let v = ds.read_raw::<f32>().unwrap();
                (
                    v.len(),
                    fnv1a(le(v.iter().map(|x| x.to_le_bytes().to_vec()).collect())),
                )
            }
            T::Unsigned(IntSize::U1) => {
                let v = ds.read_raw::<u8>().unwrap();
                (v.len(), fnv1a(v.iter().copied()))
            }
            T::Unsigned(IntSize::U4) => {
                let v = ds.read_raw::<u32>().unwrap();
                (
                    v.len(),
                    fnv1a(le(v.iter().map(|x| x.to_le_bytes().to_vec()).collect())),
                )
            }
            T::Unsigned(IntSize::U8) => {
                let v = ds.read_raw::<u64>().unwrap();
                (
                    v.len(),
                    fnv1a(le(v.iter().map(|x| x.to_le_bytes().to_vec()).collect())),
                )
            }
            other => panic!("{path}: a computed dataset of type {other:?}"),
        };
        out.push((path, n, h));
    }
}

/// The digests of every dataset a run computes (`/maps`, `/baseline`,
/// `/trajectories`, `/refine`), sorted by path.
pub fn file_digests(file: &hdf5::File) -> Vec<(String, usize, u64)> {
    let mut got = Vec::new();
    for group in ["maps", "baseline", "trajectories", "refine"] {
        if let Ok(g) = file.group(group) {
            digests(&g, &format!("/{group}"), &mut got);
        }
    }
    got
}

/// The golden lines of run `label` in `golden` (lines starting `#` are
/// comments): (path, element count, digest) each.
pub fn golden_lines(golden: &str, label: &str) -> Vec<(String, usize, u64)> {
    golden
        .lines()
        .filter(|line| !line.starts_with('#'))
        .filter_map(|line| {
            let f: Vec<&str> = line.split_whitespace().collect();
            (f[0] == label).then(|| {
                (
                    f[1].to_owned(),
                    f[2].parse().unwrap(),
                    u64::from_str_radix(f[3], 16).unwrap(),
                )
            })
        })
        .collect()
}
