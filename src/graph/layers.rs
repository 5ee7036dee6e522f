//! Array-layer ranges of an image, and per-range state. Techniques write different layers of one
//! image (each light's layer of the visibility target); tracking layers, not whole images, lets
//! two passes that write disjoint layers run with no barrier between them while a later read of
//! every layer still waits for each writer. Mips are not tracked: every umbra image has one.

use std::fmt;

/// Layers `first .. first + count` of an image (buffers count as one layer).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Layers {
    pub first: u32,
    pub count: u32,
}

impl Layers {
    pub fn one(layer: u32) -> Layers {
        Layers { first: layer, count: 1 }
    }

    /// All `count` layers of an image.
    pub fn all(count: u32) -> Layers {
        Layers { first: 0, count }
    }

    pub fn end(self) -> u32 {
        self.first + self.count
    }

    pub fn overlaps(self, other: Layers) -> bool {
        self.first < other.end() && other.first < self.end()
    }

    pub fn contains(self, other: Layers) -> bool {
        self.first <= other.first && other.end() <= self.end()
    }
}

impl fmt::Display for Layers {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.count {
            1 => write!(f, "layer {}", self.first),
            _ => write!(f, "layers {}..={}", self.first, self.end() - 1),
        }
    }
}

/// A value for each layer of a resource, kept as runs of equal values: the runs split where an
/// access's range begins or ends and merge again once their values agree.
#[derive(Clone, Debug)]
pub struct PerLayer<T> {
    runs: Vec<(Layers, T)>,
}

impl<T: Clone + PartialEq> PerLayer<T> {
    pub fn new(count: u32, value: T) -> PerLayer<T> {
        PerLayer { runs: vec![(Layers::all(count.max(1)), value)] }
    }

    /// Splits the runs so that `range`'s ends fall between runs.
    fn split_at(&mut self, at: u32) {
        if let Some(i) = self.runs.iter().position(|(r, _)| r.first < at && at < r.end()) {
            let (r, v) = self.runs[i].clone();
            self.runs[i].0 = Layers { first: r.first, count: at - r.first };
            self.runs.insert(i + 1, (Layers { first: at, count: r.end() - at }, v));
        }
    }

    /// The runs inside `range`, split at its ends, for the caller to read and update.
    pub fn runs_in(&mut self, range: Layers) -> impl Iterator<Item = &mut (Layers, T)> {
        self.split_at(range.first);
        self.split_at(range.end());
        self.runs.iter_mut().filter(move |(r, _)| range.contains(*r))
    }

    /// The runs overlapping `range` (without splitting).
    pub fn overlapping(&self, range: Layers) -> impl Iterator<Item = &(Layers, T)> {
        self.runs.iter().filter(move |(r, _)| r.overlaps(range))
    }

    /// Joins neighbouring runs whose values are equal.
    pub fn merge(&mut self) {
        let mut merged: Vec<(Layers, T)> = Vec::with_capacity(self.runs.len());
        for (r, v) in self.runs.drain(..) {
            match merged.last_mut() {
                Some((last, lv)) if *lv == v && last.end() == r.first => last.count += r.count,
                _ => merged.push((r, v)),
            }
        }
        self.runs = merged;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_split_at_a_range_and_merge_back() {
        let mut p = PerLayer::new(4, 0u32);
        for (_, v) in p.runs_in(Layers::one(2)) {
            *v = 7;
        }
        let runs: Vec<_> = p.overlapping(Layers::all(4)).cloned().collect();
        assert_eq!(runs, vec![(Layers::all(2), 0), (Layers::one(2), 7), (Layers::one(3), 0)]);
        for (_, v) in p.runs_in(Layers { first: 1, count: 3 }) {
            *v = 7;
        }
        p.merge();
        let runs: Vec<_> = p.overlapping(Layers::all(4)).cloned().collect();
        assert_eq!(runs, vec![(Layers::one(0), 0), (Layers { first: 1, count: 3 }, 7)]);
        assert_eq!(p.overlapping(Layers::one(0)).count(), 1);
    }
}
