//! What the fuzz tests share.

/// xorshift64*: deterministic, so a failure reproduces with the same count.
pub struct Rng(pub u64);

impl Rng {
    pub fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    pub fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// The committed corpus of fuzz target `name` (`tests/corpus/<name>/`): inputs replayed
/// before any mutant — the seeds relit writes (studio scenes, fitted maps, compressed
/// and RTI files) and any input that once broke a reader. CI replays them with every
/// test run.
#[allow(dead_code)]
pub fn corpus(name: &str) -> Vec<Vec<u8>> {
    let dir = corpus_dir(name);
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .map(|entries| entries.flatten().map(|e| e.path()).collect())
        .unwrap_or_default();
    files.sort();
    files.iter().filter_map(|p| std::fs::read(p).ok()).collect()
}

/// With `RELIT_FUZZ_WRITE_CORPUS=1`, store `seeds` as target `name`'s corpus (how the
/// committed corpus is made and refreshed).
#[allow(dead_code)]
pub fn store_corpus(name: &str, seeds: &[Vec<u8>]) {
    if std::env::var("RELIT_FUZZ_WRITE_CORPUS").is_ok_and(|v| v == "1") {
        let dir = corpus_dir(name);
        std::fs::create_dir_all(&dir).unwrap();
        for (i, seed) in seeds.iter().enumerate() {
            std::fs::write(dir.join(format!("seed-{i}")), seed).unwrap();
        }
    }
}

fn corpus_dir(name: &str) -> std::path::PathBuf {
    let safe: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '.' || c == '-' {
                c
            } else {
                '-'
            }
        })
        .collect();
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/corpus")
        .join(safe)
}
