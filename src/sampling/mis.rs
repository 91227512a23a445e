//! Multiple importance sampling heuristics (Veach 1997, ch. 9).

/// Power heuristic with β = 2 for one sample from each of two strategies:
/// `f² / (f² + g²)` where `f` and `g` are the strategies' densities (same measure).
#[inline]
pub fn power_heuristic(pdf_f: f32, pdf_g: f32) -> f32 {
    if pdf_f.is_infinite() {
        return 1.0;
    }
    let f2 = pdf_f * pdf_f;
    let g2 = pdf_g * pdf_g;
    if f2 + g2 == 0.0 { 0.0 } else { f2 / (f2 + g2) }
}

/// Balance heuristic for one sample from each of two strategies: `f / (f + g)`.
#[inline]
pub fn balance_heuristic(pdf_f: f32, pdf_g: f32) -> f32 {
    if pdf_f + pdf_g == 0.0 { 0.0 } else { pdf_f / (pdf_f + pdf_g) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn heuristics_of_two_strategies_sum_to_one() {
        for (a, b) in [(1.0, 2.0), (0.3, 0.0), (5.0, 5.0)] {
            assert!((power_heuristic(a, b) + power_heuristic(b, a) - 1.0).abs() < 1e-6);
            assert!((balance_heuristic(a, b) + balance_heuristic(b, a) - 1.0).abs() < 1e-6);
        }
    }
}
