//! The box-filtered mip chain of an 8-bit atlas slice: what a renderer uploads as the shell
//! and fin atlases' mip levels (`furbake-render`, and engines through `furbake-capi`) and what the stacking table reproduces on the CPU
//! (`stacking.rs`, docs/design.md "Shell opacity"), so both see the same texels.

/// Box-filtered mip chain of one `width × height` 8-bit image (level 0 first). Odd sizes are
/// handled by clamping the 2×2 footprint at the border; the chain ends at 1×1.
pub fn mip_chain(width: u32, height: u32, texels: &[u8]) -> Vec<(u32, u32, Vec<u8>)> {
    let mut levels = vec![(width, height, texels.to_vec())];
    while let Some((w, h, prev)) = levels.last().filter(|(w, h, _)| *w > 1 || *h > 1) {
        let (nw, nh) = ((*w / 2).max(1), (*h / 2).max(1));
        let (w, h) = (*w as usize, *h as usize);
        let mut next = vec![0u8; nw as usize * nh as usize];
        for y in 0..nh as usize {
            for x in 0..nw as usize {
                let (x0, y0) = ((2 * x).min(w - 1), (2 * y).min(h - 1));
                let (x1, y1) = ((2 * x + 1).min(w - 1), (2 * y + 1).min(h - 1));
                let sum = prev[y0 * w + x0] as u32
                    + prev[y0 * w + x1] as u32
                    + prev[y1 * w + x0] as u32
                    + prev[y1 * w + x1] as u32;
                next[y * nw as usize + x] = ((sum + 2) / 4) as u8;
            }
        }
        levels.push((nw, nh, next));
    }
    levels
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mip_chain_averages_and_ends_at_one_texel() {
        let levels = mip_chain(4, 2, &[0, 255, 100, 100, 255, 0, 100, 100]);
        let sizes: Vec<(u32, u32)> = levels.iter().map(|(w, h, _)| (*w, *h)).collect();
        assert_eq!(sizes, [(4, 2), (2, 1), (1, 1)]);
        assert_eq!(levels[1].2, [128, 100]);
        assert_eq!(levels[2].2, [114]);
        let odd = mip_chain(3, 3, &[9; 9]);
        assert_eq!(odd.len(), 2);
        assert_eq!(odd[1].2, [9], "a constant image stays constant");
    }
}
