//! The symbol table: tile byte -> symbol index (docs/rules.md §9.1).

/// Symbol index of every byte; unknown bytes map to 0 (blank).
pub(crate) const SYMBOL_OF_TILE: [u8; 256] = build();

const fn build() -> [u8; 256] {
    let mut t = [0u8; 256];
    t[b'@' as usize] = 1;
    t[b'#' as usize] = 2;
    t[b'.' as usize] = 3;
    t[b'-' as usize] = 4;
    t[b'|' as usize] = 4;
    t[b'%' as usize] = 5;
    t[b'+' as usize] = 6;
    t[b'^' as usize] = 7;
    t[b'!' as usize] = 8;
    t[b'?' as usize] = 9;
    t[b']' as usize] = 10;
    t[b')' as usize] = 11;
    t[b'/' as usize] = 12;
    t[b'*' as usize] = 13;
    t[b':' as usize] = 14;
    t[b'=' as usize] = 15;
    t[b',' as usize] = 16;
    let mut c = 0;
    while c < 26 {
        t[(b'A' + c) as usize] = 17 + c;
        c += 1;
    }
    t
}
