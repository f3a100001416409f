//! Per-stage timing: CPU spans for host stages, GPU spans for dispatches (from Vulkan
//! timestamps), written as a Chrome trace-event file (opens in Perfetto) and summarised
//! in a table on stderr. Each host stage records the process's memory at its end (its
//! resident set and peak resident set, from /proc/self/status where there is one), and a
//! stage that allocates device memory may record how much.
use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

#[derive(Clone, Debug)]
pub struct Span {
    pub name: String,
    pub gpu: bool,
    pub start_us: f64,
    pub dur_us: f64,
    /// Host stages: the resident set and the peak resident set at the stage's end (bytes;
    /// None where the system does not say).
    pub host_bytes: Option<(u64, u64)>,
    /// The device memory the stage allocated (bytes), where it says.
    pub device_bytes: Option<u64>,
    /// The scene upload: each kind of scene data read by address (its name, bytes and
    /// chunks; `GpuScene::data`).
    pub data: Vec<(&'static str, u64, usize)>,
}

/// The process's resident set and peak resident set (VmRSS, VmHWM) in bytes.
pub fn host_memory() -> Option<(u64, u64)> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let field = |name: &str| -> Option<u64> {
        let line = status.lines().find(|l| l.starts_with(name))?;
        let kb: u64 = line[name.len()..]
            .trim()
            .trim_end_matches("kB")
            .trim()
            .parse()
            .ok()?;
        Some(kb * 1024)
    };
    Some((field("VmRSS:")?, field("VmHWM:")?))
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
            host_bytes: host_memory(),
            device_bytes: None,
            data: Vec::new(),
        });
        out
    }

    /// Records that the last stage allocated `bytes` of device memory.
    pub fn device_bytes(&mut self, bytes: u64) {
        if let Some(s) = self.spans.last_mut() {
            s.device_bytes = Some(bytes);
        }
    }

    /// Records the last stage's scene data: per kind, its name, bytes and chunks.
    pub fn scene_data(&mut self, kinds: Vec<(&'static str, u64, usize)>) {
        if let Some(s) = self.spans.last_mut() {
            s.data = kinds;
        }
    }

    pub fn add_gpu(&mut self, name: &str, start_us: f64, dur_us: f64) {
        self.spans.push(Span {
            name: name.to_string(),
            gpu: true,
            start_us,
            dur_us,
            host_bytes: None,
            device_bytes: None,
            data: Vec::new(),
        });
    }

    /// The Chrome trace-event JSON (an array of complete events).
    pub fn to_json(&self) -> String {
        let events: Vec<serde_json::Value> = self
            .spans
            .iter()
            .map(|s| {
                let mut e = serde_json::json!({
                    "name": s.name,
                    "cat": if s.gpu { "gpu" } else { "cpu" },
                    "ph": "X",
                    "ts": s.start_us,
                    "dur": s.dur_us,
                    "pid": 1,
                    "tid": if s.gpu { 2 } else { 1 },
                });
                let mut args = serde_json::Map::new();
                if let Some((rss, peak)) = s.host_bytes {
                    args.insert("host_bytes".into(), rss.into());
                    args.insert("host_peak_bytes".into(), peak.into());
                }
                if let Some(d) = s.device_bytes {
                    args.insert("device_bytes".into(), d.into());
                }
                for (name, bytes, chunks) in &s.data {
                    args.insert(
                        format!("data {name}"),
                        serde_json::json!({ "bytes": bytes, "chunks": chunks }),
                    );
                }
                if !args.is_empty() {
                    e["args"] = serde_json::Value::Object(args);
                }
                e
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
        let mut by: BTreeMap<(bool, String), (usize, f64, u64)> = BTreeMap::new();
        let mut order: Vec<(bool, String)> = Vec::new();
        for s in &self.spans {
            let key = (s.gpu, s.name.clone());
            let e = by.entry(key.clone()).or_insert_with(|| {
                order.push(key.clone());
                (0, 0.0, 0)
            });
            e.0 += 1;
            e.1 += s.dur_us;
            e.2 = e.2.max(s.host_bytes.map_or(0, |m| m.1));
        }
        let mut out = format!(
            "{:<32} {:>4} {:>7} {:>12} {:>12} {:>13}\n",
            "stage", "on", "count", "total ms", "mean ms", "host peak MB"
        );
        for key in order {
            let (n, total, peak) = by[&key];
            let peak = if peak > 0 {
                format!("{:.0}", peak as f64 / 1e6)
            } else {
                String::new()
            };
            out.push_str(&format!(
                "{:<32} {:>4} {:>7} {:>12.2} {:>12.3} {:>13}\n",
                key.1,
                if key.0 { "gpu" } else { "cpu" },
                n,
                total / 1e3,
                total / 1e3 / n as f64,
                peak
            ));
        }
        out
    }
}
