//! A least-recently-used map bounded by the total weight (bytes) of its values: the memory
//! bound of the asset cache and of each decode worker's states.

use std::collections::{BTreeMap, HashMap};
use std::hash::Hash;

pub struct Lru<K, V> {
    map: HashMap<K, Slot<V>>,
    /// Use order: the smallest tick is the least recently used key.
    order: BTreeMap<u64, K>,
    tick: u64,
    weight: u64,
    capacity: u64,
}

struct Slot<V> {
    value: V,
    weight: u64,
    tick: u64,
}

impl<K: Hash + Eq + Clone, V> Lru<K, V> {
    pub fn new(capacity: u64) -> Self {
        Lru { map: HashMap::new(), order: BTreeMap::new(), tick: 0, weight: 0, capacity }
    }

    fn next_tick(&mut self) -> u64 {
        self.tick += 1;
        self.tick
    }

    /// The value, marked as just used.
    pub fn get(&mut self, key: &K) -> Option<&mut V> {
        let t = self.next_tick();
        let slot = self.map.get_mut(key)?;
        self.order.remove(&slot.tick);
        slot.tick = t;
        self.order.insert(t, key.clone());
        Some(&mut slot.value)
    }

    /// The value without changing the use order.
    #[cfg(test)]
    pub fn peek(&self, key: &K) -> Option<&V> {
        self.map.get(key).map(|s| &s.value)
    }

    /// Inserts (or replaces) a value and evicts least recently used ones until the total fits.
    /// A value heavier than the whole capacity is not kept. Returns what left the map, so that
    /// the caller can drop it outside any lock.
    pub fn insert(&mut self, key: K, value: V, weight: u64) -> Vec<V> {
        let mut out: Vec<V> = self.remove(&key).into_iter().collect();
        if weight > self.capacity {
            out.push(value);
            return out;
        }
        // Each pass removes one entry, so this ends within len() passes.
        while self.weight + weight > self.capacity {
            match self.order.pop_first() {
                Some((_, k)) => {
                    if let Some(s) = self.map.remove(&k) {
                        self.weight -= s.weight;
                        out.push(s.value);
                    }
                }
                None => break,
            }
        }
        let t = self.next_tick();
        self.order.insert(t, key.clone());
        self.map.insert(key, Slot { value, weight, tick: t });
        self.weight += weight;
        out
    }

    pub fn remove(&mut self, key: &K) -> Option<V> {
        let s = self.map.remove(key)?;
        self.order.remove(&s.tick);
        self.weight -= s.weight;
        Some(s.value)
    }

    /// Removes every entry whose key fails `keep`.
    pub fn retain(&mut self, mut keep: impl FnMut(&K) -> bool) -> Vec<V> {
        let gone: Vec<K> = self.map.keys().filter(|k| !keep(k)).cloned().collect();
        gone.iter().filter_map(|k| self.remove(k)).collect()
    }

    pub fn len(&self) -> usize {
        self.map.len()
    }

    pub fn weight(&self) -> u64 {
        self.weight
    }

    pub fn capacity(&self) -> u64 {
        self.capacity
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn evicts_least_recently_used_by_weight() {
        let mut l = Lru::new(10);
        assert!(l.insert("a", 1, 4).is_empty());
        assert!(l.insert("b", 2, 4).is_empty());
        assert_eq!(l.get(&"a"), Some(&mut 1)); // a is now newer than b
        assert_eq!(l.insert("c", 3, 4), vec![2]);
        assert_eq!((l.len(), l.weight()), (2, 8));
        assert!(l.peek(&"b").is_none() && l.peek(&"a").is_some());
        assert_eq!(l.insert("huge", 9, 11), vec![9], "heavier than the capacity: not kept");
        assert_eq!(l.insert("a", 5, 2), vec![1], "replacing returns the old value");
        assert_eq!(l.weight(), 6);
        assert_eq!(l.retain(|k| *k != "c"), vec![3]);
        assert_eq!((l.len(), l.weight()), (1, 2));
    }
}
