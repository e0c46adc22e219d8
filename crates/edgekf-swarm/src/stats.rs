//! Per-link message statistics (`network.csv`): per directed link and channel, the messages
//! sent, received, late (arrived after the receiver had to go on without them) and lost (never
//! arrived), and the latency's median and 99th percentile from a log-scale histogram (bins of
//! 1/64 decade, about 3.7 % wide: the percentiles are the bins' geometric centres).

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

/// Bins per decade of the latency histogram.
const PER_DECADE: f64 = 64.0;

/// One link's counts and latency histogram (latencies in µs, bin = ⌊64 log10 µs⌋).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct LinkStats {
    /// Messages the sender published towards this receiver.
    pub sent: u64,
    /// Messages that arrived (on time or late).
    pub received: u64,
    /// Messages that arrived after the receiver went on without them.
    pub late: u64,
    /// Messages expected and never arrived.
    pub lost: u64,
    /// Latency histogram: bin → count.
    pub latency: BTreeMap<i32, u64>,
}

impl LinkStats {
    /// A message that arrived `latency_us` after it was sent.
    pub fn arrived(&mut self, latency_us: f64, late: bool) {
        self.received += 1;
        self.late += u64::from(late);
        let bin = (latency_us.max(0.1).log10() * PER_DECADE).floor() as i32;
        *self.latency.entry(bin).or_default() += 1;
    }

    /// The latency quantile `q` in ms (NaN without samples).
    pub fn quantile_ms(&self, q: f64) -> f64 {
        let total: u64 = self.latency.values().sum();
        if total == 0 {
            return f64::NAN;
        }
        let want = (q * total as f64).ceil().max(1.0) as u64;
        let mut seen = 0;
        for (&bin, &n) in &self.latency {
            seen += n;
            if seen >= want {
                return 10f64.powf((f64::from(bin) + 0.5) / PER_DECADE) / 1000.0;
            }
        }
        f64::NAN
    }

    /// Adds another's counts.
    pub fn merge(&mut self, o: &LinkStats) {
        self.sent += o.sent;
        self.received += o.received;
        self.late += o.late;
        self.lost += o.lost;
        for (b, n) in &o.latency {
            *self.latency.entry(*b).or_default() += n;
        }
    }
}

/// A directed link: sender, receiver (`None`: the world) and channel.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
pub struct Link {
    /// The sender (`None`: the world).
    pub from: Option<usize>,
    /// The receiver (`None`: the world).
    pub to: Option<usize>,
    /// `sensing`, `output`, `input` or `exchange`.
    pub channel: String,
}

/// Every link's statistics.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct NetworkStats {
    /// Per link.
    pub links: Vec<(Link, LinkStats)>,
}

impl NetworkStats {
    /// `network.csv`: `from,to,channel,sent,received,late,lost,latency_p50_ms,latency_p99_ms`,
    /// one row per directed link and channel (`world` for the world), sorted.
    pub fn csv(&self) -> String {
        let mut rows: Vec<&(Link, LinkStats)> = self.links.iter().collect();
        rows.sort_by(|a, b| a.0.cmp(&b.0));
        let who = |x: Option<usize>| x.map_or("world".to_string(), |i| i.to_string());
        let mut out =
            String::from("from,to,channel,sent,received,late,lost,latency_p50_ms,latency_p99_ms\n");
        for (l, s) in rows {
            out.push_str(&format!(
                "{},{},{},{},{},{},{},{},{}\n",
                who(l.from),
                who(l.to),
                l.channel,
                s.sent,
                s.received,
                s.late,
                s.lost,
                fmt_ms(s.quantile_ms(0.5)),
                fmt_ms(s.quantile_ms(0.99)),
            ));
        }
        out
    }

    /// Totals of a channel over every link.
    pub fn total(&self, channel: &str) -> LinkStats {
        let mut t = LinkStats::default();
        for (l, s) in &self.links {
            if l.channel == channel {
                t.merge(s);
            }
        }
        t
    }
}

fn fmt_ms(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.4}")
    } else {
        String::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_come_from_the_histogram_within_a_bin() {
        let mut s = LinkStats::default();
        for us in 1..=1000 {
            s.arrived(f64::from(us), false);
        }
        let p50 = s.quantile_ms(0.5);
        let p99 = s.quantile_ms(0.99);
        // Bins are 1/64 decade (3.7 %) wide; the centre is within 2 % of any value in it.
        assert!((p50 / 0.5 - 1.0).abs() < 0.04, "{p50}");
        assert!((p99 / 0.99 - 1.0).abs() < 0.04, "{p99}");
        assert!(LinkStats::default().quantile_ms(0.5).is_nan());
    }
}
