//! Import of a generated 2,000-entry EDS (records, compact arrays, `$NODEID` defaults, limits,
//! comments, mixed case), strict mode: the requirement is under 10 ms. Also the dictionary built
//! from it and the export back. Prints the median import time against the requirement.

use criterion::{criterion_group, criterion_main, Criterion};
use duocan::eds::{export_eds, Description, ExportOptions, ImportOptions};
use std::hint::black_box;
use std::time::{Duration, Instant};

#[path = "../tests/eds/generate.rs"]
mod generate;

fn eds(c: &mut Criterion) {
    let text = generate::eds(2000);
    let opts = ImportOptions::strict();
    let import = || Description::parse(black_box(text.as_bytes()), "large.eds", &opts).unwrap();
    let d = import();
    assert_eq!(d.len(), 2000);
    let od = d.dictionary(5);
    let mut g = c.benchmark_group("eds");
    g.bench_function("import_2000_entries", |b| b.iter(import));
    g.bench_function("dictionary_2000_entries", |b| {
        b.iter(|| black_box(&d).dictionary(5))
    });
    g.bench_function("export_2000_entries", |b| {
        b.iter(|| export_eds(black_box(&od), &ExportOptions::default()).unwrap())
    });
    g.finish();

    // The figure against the requirement: the median of 101 imports.
    let mut times: Vec<Duration> = (0..101)
        .map(|_| {
            let t = Instant::now();
            black_box(import());
            t.elapsed()
        })
        .collect();
    times.sort();
    let median = times[times.len() / 2];
    println!(
        "EDS import, {} bytes, 2,000 entries: {:.2} ms (median of 101); required < 10 ms",
        text.len(),
        median.as_secs_f64() * 1e3
    );
    assert!(
        median < Duration::from_millis(10),
        "import takes {median:?}"
    );
}

criterion_group!(benches, eds);
criterion_main!(benches);
