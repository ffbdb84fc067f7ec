//! Env calls (off the hot path: attribute reads and writes, method calls, renders): their
//! files and the format both sides read and write.
//!
//! A call file holds entries `[u32 row][u64 len][len bytes]` (little endian), `row` being the
//! env's index in its worker's block. The supervisor writes the requests, the worker the
//! replies; each file is written to a temporary name and renamed, so it is never read half
//! written.

use std::path::{Path, PathBuf};

use rogue_gym_ipc::PoolId;

/// Where the supervisor puts the call requests of worker `k`, generation `generation`.
pub(crate) fn request_path(id: &PoolId, k: usize, generation: u64) -> PathBuf {
    id.aux_dir()
        .join(format!("w{k}.g{generation}.call-request"))
}

/// Where worker `k`, generation `generation`, puts its call replies.
pub(crate) fn reply_path(id: &PoolId, k: usize, generation: u64) -> PathBuf {
    id.aux_dir().join(format!("w{k}.g{generation}.call-reply"))
}

/// Where the supervisor puts the action extras of worker `k`'s next step (generation
/// `generation`), in the format of a call file: one entry per env that has any.
pub(crate) fn action_extras_path(id: &PoolId, k: usize, generation: u64) -> PathBuf {
    id.aux_dir()
        .join(format!("w{k}.g{generation}.action-extras"))
}

/// Encode `(row, bytes)` entries.
pub fn encode(entries: &[(u32, &[u8])]) -> Vec<u8> {
    let mut out = Vec::with_capacity(entries.iter().map(|(_, b)| 12 + b.len()).sum());
    for (row, bytes) in entries {
        out.extend_from_slice(&row.to_le_bytes());
        out.extend_from_slice(&(bytes.len() as u64).to_le_bytes());
        out.extend_from_slice(bytes);
    }
    out
}

/// Decode entries written by [`encode`].
pub fn decode(mut data: &[u8]) -> Result<Vec<(u32, Vec<u8>)>, String> {
    let mut out = Vec::new();
    while !data.is_empty() {
        if data.len() < 12 {
            return Err(format!(
                "truncated call entry header ({} bytes)",
                data.len()
            ));
        }
        let row = u32::from_le_bytes(data[..4].try_into().expect("4 bytes"));
        let len = u64::from_le_bytes(data[4..12].try_into().expect("8 bytes"));
        let len = usize::try_from(len).map_err(|_| format!("call entry of {len} bytes"))?;
        let body = data
            .get(12..12 + len)
            .ok_or_else(|| format!("truncated call entry: {len} bytes announced"))?;
        out.push((row, body.to_vec()));
        data = &data[12 + len..];
    }
    Ok(out)
}

/// Write a call file: private, to a temporary name, then renamed.
pub(crate) fn write(path: &Path, data: &[u8]) -> Result<(), String> {
    rogue_gym_ipc::private::write_private_file(path, data).map_err(|e| e.to_string())
}

/// Read and remove a call file; it must be a private file of this user (its bytes are
/// unpickled by hosted envs).
pub(crate) fn take(path: &Path) -> Result<Vec<(u32, Vec<u8>)>, String> {
    let data = rogue_gym_ipc::private::read_private_file(path).map_err(|e| e.to_string())?;
    let _ = std::fs::remove_file(path);
    decode(&data)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn entries_round_trip_and_truncation_is_an_error() {
        let data = encode(&[(0, b"ab"), (3, b""), (7, &[1, 2, 3])]);
        let back = decode(&data).unwrap();
        assert_eq!(
            back,
            vec![(0, b"ab".to_vec()), (3, vec![]), (7, vec![1, 2, 3])]
        );
        assert!(decode(&data[..data.len() - 1]).is_err());
        assert!(decode(&data[..5]).is_err());
    }
}
