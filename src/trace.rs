//! Per-stage timing: CPU spans for host stages, GPU spans for dispatches (from Vulkan
//! timestamps), written as a Chrome trace-event file (opens in Perfetto) and summarised
//! in a table on stderr.
use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

#[derive(Clone, Debug)]
pub struct Span {
    pub name: String,
    pub gpu: bool,
    pub start_us: f64,
    pub dur_us: f64,
}

pub struct Trace {
    origin: Instant,
    pub spans: Vec<Span>,
}

impl Default for Trace {
    fn default() -> Self {
        Self::new()
    }
}

impl Trace {
    pub fn new() -> Trace {
        Trace {
            origin: Instant::now(),
            spans: Vec::new(),
        }
    }

    /// Microseconds since the trace began.
    pub fn now_us(&self) -> f64 {
        self.origin.elapsed().as_secs_f64() * 1e6
    }

    /// Time a host stage.
    pub fn cpu<T>(&mut self, name: &str, f: impl FnOnce() -> T) -> T {
        let start = self.now_us();
        let out = f();
        let end = self.now_us();
        self.spans.push(Span {
            name: name.to_string(),
            gpu: false,
            start_us: start,
            dur_us: end - start,
        });
        out
    }

    pub fn add_gpu(&mut self, name: &str, start_us: f64, dur_us: f64) {
        self.spans.push(Span {
            name: name.to_string(),
            gpu: true,
            start_us,
            dur_us,
        });
    }

    /// The Chrome trace-event JSON (an array of complete events).
    pub fn to_json(&self) -> String {
        let events: Vec<serde_json::Value> = self
            .spans
            .iter()
            .map(|s| {
                serde_json::json!({
                    "name": s.name,
                    "cat": if s.gpu { "gpu" } else { "cpu" },
                    "ph": "X",
                    "ts": s.start_us,
                    "dur": s.dur_us,
                    "pid": 1,
                    "tid": if s.gpu { 2 } else { 1 },
                })
            })
            .chain([
                serde_json::json!({"name": "thread_name", "ph": "M", "pid": 1, "tid": 1, "args": {"name": "host (CPU)"}}),
                serde_json::json!({"name": "thread_name", "ph": "M", "pid": 1, "tid": 2, "args": {"name": "device (GPU dispatches)"}}),
            ])
            .collect();
        serde_json::json!({ "traceEvents": events, "displayTimeUnit": "ms" }).to_string()
    }

    pub fn write(&self, path: &Path) -> anyhow::Result<()> {
        crate::io::write_atomic(path, self.to_json().as_bytes())
    }

    /// Per-stage totals: stage, where, count, total ms, mean ms.
    pub fn summary(&self) -> String {
        let mut by: BTreeMap<(bool, String), (usize, f64, f64)> = BTreeMap::new();
        let mut order: Vec<(bool, String)> = Vec::new();
        for s in &self.spans {
            let key = (s.gpu, s.name.clone());
            let e = by.entry(key.clone()).or_insert_with(|| {
                order.push(key.clone());
                (0, 0.0, s.start_us)
            });
            e.0 += 1;
            e.1 += s.dur_us;
        }
        let mut out = format!(
            "{:<32} {:>4} {:>7} {:>12} {:>12}\n",
            "stage", "on", "count", "total ms", "mean ms"
        );
        for key in order {
            let (n, total, _) = by[&key];
            out.push_str(&format!(
                "{:<32} {:>4} {:>7} {:>12.2} {:>12.3}\n",
                key.1,
                if key.0 { "gpu" } else { "cpu" },
                n,
                total / 1e3,
                total / 1e3 / n as f64
            ));
        }
        out
    }
}
