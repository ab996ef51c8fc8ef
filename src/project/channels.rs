//! PROJECT: the named channels of a map.
//!
//! A map's tensor is H x W x C float32; which quantity each of the C planes holds is a list of
//! [`Channel`]s that travels with every frame (in memory, in shard messages and metadata). Code
//! asks for a channel by name ([`Channels::index`]), never by position. The `.npy` layout is
//! SqueezeSeg's ([`Channels::npy`]: 6 channels, or 9 with colour); shards store the inputs only
//! (the label travels as its own array).

use serde::{Deserialize, Serialize};

/// One plane of the tensor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Channel {
    /// Velodyne x, metres.
    X,
    /// Velodyne y, metres.
    Y,
    /// Velodyne z, metres.
    Z,
    /// Reflectance, 0-1.
    Intensity,
    /// Distance to the sensor, metres; 0 marks an empty cell.
    Range,
    /// Class id (as a float).
    Label,
    /// Red, 0-1 (0 where the camera does not see the point).
    R,
    /// Green, 0-1.
    G,
    /// Blue, 0-1.
    B,
}

// Every channel (`Channel::ALL`) in SqueezeSeg's `.npy` order (the first six without colour).
crate::named_enum!(Channel, "channel", [
    X => "x" [] "velodyne x, metres",
    Y => "y" [] "velodyne y, metres",
    Z => "z" [] "velodyne z, metres",
    Intensity => "intensity" [] "reflectance, 0-1",
    Range => "range" [] "distance to the sensor, metres; 0 marks an empty cell",
    Label => "label" [] "class id",
    R => "r" [] "red, 0-1",
    G => "g" [] "green, 0-1",
    B => "b" [] "blue, 0-1",
]);

/// The channels of a tensor, in plane order.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Channels(pub Vec<Channel>);

impl Channels {
    /// The `.npy` layout: SqueezeSeg's six (x, y, z, intensity, range, label), then r, g, b
    /// with colour.
    pub fn npy(rgb: bool) -> Channels {
        Channels(Channel::ALL[..if rgb { 9 } else { 6 }].to_vec())
    }

    /// The `.npy` layout of a tensor `depth` planes deep (6 or 9), if it is one.
    pub fn npy_of_depth(depth: usize) -> Option<Channels> {
        match depth {
            6 => Some(Channels::npy(false)),
            9 => Some(Channels::npy(true)),
            _ => None,
        }
    }

    /// Number of planes.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// True without planes.
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }

    /// The plane of `c`, if present.
    pub fn index(&self, c: Channel) -> Option<usize> {
        self.0.iter().position(|&x| x == c)
    }

    /// Whether `c` is present.
    pub fn has(&self, c: Channel) -> bool {
        self.index(c).is_some()
    }

    /// Whether the colour planes are present.
    pub fn has_rgb(&self) -> bool {
        self.has(Channel::R)
    }

    /// The network's inputs: every channel but the label.
    pub fn inputs(&self) -> Channels {
        Channels(
            self.0
                .iter()
                .copied()
                .filter(|&c| c != Channel::Label)
                .collect(),
        )
    }

    /// The names, in order.
    pub fn names(&self) -> Vec<&'static str> {
        self.0.iter().map(|c| c.as_str()).collect()
    }

    /// Parses names (as stored in shards); the unknown name is returned as the error.
    pub fn from_names<S: AsRef<str>>(names: &[S]) -> Result<Channels, String> {
        names
            .iter()
            .map(|n| n.as_ref().parse().map_err(|_| n.as_ref().to_string()))
            .collect::<Result<Vec<_>, _>>()
            .map(Channels)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layouts() {
        let c = Channels::npy(true);
        assert_eq!(c.index(Channel::Range), Some(4));
        assert_eq!(c.index(Channel::Label), Some(5));
        assert_eq!(
            c.inputs().names(),
            ["x", "y", "z", "intensity", "range", "r", "g", "b"]
        );
        assert_eq!(Channels::from_names(&["x", "q"]), Err("q".to_string()));
        assert_eq!(Channels::npy_of_depth(6), Some(Channels::npy(false)));
    }
}
