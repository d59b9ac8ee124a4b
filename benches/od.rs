//! Dictionary lookup of a random existing entry in a 1,500-entry dictionary (the published
//! embedded master's size): static and dynamic dictionaries, and that master's own hash table
//! for comparison. The static dictionary's perfect hash should be the fastest of the three.

use criterion::{criterion_group, criterion_main, Criterion};
use duocan::od::{DataType, DynamicDictionary, ObjectDef, ObjectDictionary, StaticDictionary};
use std::hint::black_box;

const ENTRIES: usize = 1_500;

/// A master-like layout: communication objects, many small records, some arrays.
fn layout() -> Vec<ObjectDef> {
    let mut defs = Vec::new();
    let mut index = 0x1000u16;
    while defs.len() < ENTRIES {
        let subs = 1 + (index as usize * 7) % 12;
        for sub in 0..subs.min(ENTRIES - defs.len()) {
            defs.push(ObjectDef::new(index, sub as u8, DataType::Unsigned32));
        }
        index += if index < 0x2000 { 1 } else { 3 };
        if index == 0x1FFF {
            index = 0x2000;
        }
    }
    defs
}

/// Random existing keys, fixed seed.
fn probes(defs: &[ObjectDef]) -> Vec<(u16, u8)> {
    let mut rng = fastrand::Rng::with_seed(7);
    (0..4096)
        .map(|_| {
            let d = &defs[rng.usize(..defs.len())];
            (d.index, d.sub)
        })
        .collect()
}

/// The published embedded master's table: 512 buckets, hash ((index·1438) >> 2) + sub mod 512,
/// chained overflow.
struct PublishedTable {
    heads: Vec<Option<usize>>,
    nodes: Vec<(u16, u8, u32, Option<usize>)>,
}

impl PublishedTable {
    fn hash(index: u16, sub: u8) -> usize {
        ((((index as u32) * 1438) >> 2) + sub as u32) as usize % 512
    }
    fn new(defs: &[ObjectDef]) -> Self {
        let mut t = PublishedTable {
            heads: vec![None; 512],
            nodes: Vec::new(),
        };
        for d in defs {
            let h = Self::hash(d.index, d.sub);
            t.nodes.push((d.index, d.sub, 0, t.heads[h]));
            t.heads[h] = Some(t.nodes.len() - 1);
        }
        t
    }
    fn get(&self, index: u16, sub: u8) -> Option<&u32> {
        let mut cur = self.heads[Self::hash(index, sub)];
        while let Some(i) = cur {
            let n = &self.nodes[i];
            if n.0 == index && n.1 == sub {
                return Some(&n.2);
            }
            cur = n.3;
        }
        None
    }
}

fn lookup(c: &mut Criterion) {
    let defs = layout();
    let keys = probes(&defs);
    let leaked: &'static [ObjectDef] = Box::leak(defs.clone().into_boxed_slice());
    let mut st: Box<StaticDictionary<2048, 8192>> = Box::new(StaticDictionary::new());
    st.load(1, &[leaked]).expect("static dictionary fits");
    let dy = DynamicDictionary::from_tables(1, &[&defs]).expect("dynamic dictionary builds");
    let published = PublishedTable::new(&defs);
    assert_eq!(st.len(), ENTRIES);
    assert_eq!(dy.len(), ENTRIES);

    let mut g = c.benchmark_group("od_lookup_1500");
    let mut i = 0usize;
    g.bench_function("static", |b| {
        b.iter(|| {
            i = (i + 1) & 4095;
            let (x, s) = keys[i];
            black_box(st.get(black_box(x), black_box(s)).is_ok())
        })
    });
    g.bench_function("dynamic", |b| {
        b.iter(|| {
            i = (i + 1) & 4095;
            let (x, s) = keys[i];
            black_box(dy.get(black_box(x), black_box(s)).is_ok())
        })
    });
    g.bench_function("published_hash_512", |b| {
        b.iter(|| {
            i = (i + 1) & 4095;
            let (x, s) = keys[i];
            black_box(published.get(black_box(x), black_box(s)).is_some())
        })
    });
    g.finish();

    // The ratio side by side, from one plain timing loop over the same probes.
    let per_lookup = |f: &dyn Fn(u16, u8) -> bool| {
        let start = std::time::Instant::now();
        let mut hits = 0u32;
        for _ in 0..2_000 {
            for (x, s) in &keys {
                hits += f(black_box(*x), black_box(*s)) as u32;
            }
        }
        assert_eq!(hits as usize, 2_000 * keys.len());
        start.elapsed().as_nanos() as f64 / (2_000 * keys.len()) as f64
    };
    let s = per_lookup(&|x, y| st.get(x, y).is_ok());
    let d = per_lookup(&|x, y| dy.get(x, y).is_ok());
    let h = per_lookup(&|x, y| published.get(x, y).is_some());
    println!(
        "lookup in 1,500 entries: static {s:.2} ns, dynamic {d:.2} ns, the published design's \
         512-bucket table {h:.2} ns; published/static = {:.2}, published/dynamic = {:.2} (above 1: \
         duocan is faster), dynamic/static = {:.2} (above 1: the static one is the fastest)",
        h / s,
        h / d,
        d / s
    );
}

criterion_group!(benches, lookup);
criterion_main!(benches);
