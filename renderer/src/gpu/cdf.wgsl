// The search of a CDF over triangles by area (the ISMs' point clouds and the bounce's candidate
// points are drawn with it): the first index in [0, count) whose entry is not below u (count - 1
// when none is), a binary search in the module's `cdf` binding, which each shader that puts
// this file in front of its own (ism.rs, bounce.rs) declares.

fn cdf_search(u: f32, count: u32) -> u32 {
    var lo = 0u;
    var hi = count - 1u;
    while lo < hi {
        let mid = (lo + hi) / 2u;
        if cdf[mid] < u {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    return lo;
}
