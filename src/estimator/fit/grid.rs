//! The grid of the index values: quantiles of a strided sample by radix selection.

/// Quantile of a strided sample of at most 1e6 values (exact for shorter series):
/// linear interpolation between the order statistics of ranks floor(q (n - 1)) and
/// the next (type 7 of Hyndman and Fan 1996, numpy's default), in
/// [`f64::total_cmp`]'s order.
///
/// The order statistics by radix selection: the values' keys
/// ([`total_order_key`]) are counted by their top 16 bits, which gives the bucket
/// and the rank within it of every order statistic asked for; only the values of
/// those buckets are then copied and selected among (nearly all of them when one
/// bucket holds most values, as a copy of all did before). The values a full sort
/// would put at those ranks (tested against one).
pub(super) fn quantiles(
    u: impl Fn(usize) -> f64,
    rows: std::ops::Range<usize>,
    qs: &[f64],
) -> Vec<f64> {
    let n = rows.len();
    let stride = n.div_ceil(1_000_000).max(1);
    // the values, read twice where they are (the counting copies none)
    let values = || rows.clone().step_by(stride).map(&u);
    let len = values().len();
    if len == 0 {
        return vec![f64::NAN; qs.len()];
    }
    const SHIFT: u32 = 48;
    let mut counts = vec![0u32; 1 << (64 - SHIFT)];
    for x in values() {
        counts[(total_order_key(x) >> SHIFT) as usize] += 1;
    }
    // every rank asked for: floor(q (n - 1)) and the next one
    let last = len - 1;
    let at: Vec<(usize, f64)> = qs
        .iter()
        .map(|q| {
            let pos = q * last as f64;
            (pos.floor() as usize, pos - pos.floor())
        })
        .collect();
    let mut ranks: Vec<usize> = at
        .iter()
        .flat_map(|&(i, _)| [i.min(last), (i + 1).min(last)])
        .collect();
    ranks.sort_unstable();
    ranks.dedup();
    // (bucket, rank of its first value) of each rank
    let mut first_rank = Vec::with_capacity(ranks.len());
    let (mut bucket, mut below) = (0usize, 0usize);
    for &r in &ranks {
        while below + counts[bucket] as usize <= r {
            below += counts[bucket] as usize;
            bucket += 1;
        }
        first_rank.push((bucket, below));
    }
    let mut buckets: Vec<usize> = first_rank.iter().map(|&(b, _)| b).collect();
    buckets.dedup();
    let mut members: Vec<Vec<f64>> = buckets
        .iter()
        .map(|&b| Vec::with_capacity(counts[b] as usize))
        .collect();
    for x in values() {
        let b = (total_order_key(x) >> SHIFT) as usize;
        if let Ok(k) = buckets.binary_search(&b) {
            members[k].push(x);
        }
    }
    // the order statistics, ranks in increasing order: after selecting local rank
    // i, every larger one lies in m[i + 1..], so the next selects within what is left
    let mut stats = vec![f64::NAN; ranks.len()];
    let mut from = 0;
    let mut last_bucket = usize::MAX;
    for (k, (&r, &(b, below))) in ranks.iter().zip(&first_rank).enumerate() {
        if b != last_bucket {
            (from, last_bucket) = (0, b);
        }
        let m = &mut members[buckets.binary_search(&b).expect("its bucket")];
        let i = r - below;
        stats[k] = *m[from..].select_nth_unstable_by(i - from, f64::total_cmp).1;
        from = i;
    }
    let order_stat = |r: usize| stats[ranks.binary_search(&r).expect("a rank asked for")];
    at.iter()
        .map(|&(i, frac)| {
            let i = i.min(last);
            let vi = order_stat(i);
            if i < last {
                vi + frac * (order_stat(i + 1) - vi)
            } else {
                vi
            }
        })
        .collect()
}

/// A u64 whose unsigned order is [`f64::total_cmp`]'s order of `x`: the sign bit set
/// for positive values, every bit flipped for negative ones (IEEE 754-2008, 5.10,
/// totalOrder).
pub(super) fn total_order_key(x: f64) -> u64 {
    let b = x.to_bits();
    if b >> 63 == 1 { !b } else { b | (1 << 63) }
}
