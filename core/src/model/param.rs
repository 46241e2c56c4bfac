//! Identifiable parameters: what calibration may change, with names, units and priors.

use serde::{Deserialize, Serialize};

/// The physical quantity of a parameter; the value is always stored in SI.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Quantity {
    /// metres
    Length,
    /// radians
    Angle,
    /// a ratio or gain without unit
    Dimensionless,
    /// radians per newton-metre (joint compliance)
    Compliance,
    /// kilograms
    Mass,
    /// newton-metres squared (flexural rigidity EI, torsional rigidity GJ)
    Rigidity,
    /// per kelvin (thermal expansion)
    PerKelvin,
    /// radians per newton (lateral compliance per unit bending moment arm), or other derived units
    Other(&'static str),
}

impl Quantity {
    /// `value` (SI) in the unit a field engineer reads it in: mm, degrees, or SI in
    /// scientific notation.
    pub fn readable(&self, value: f64) -> String {
        match self {
            Quantity::Length => format!("{:.3} mm", value * 1e3),
            Quantity::Angle => format!("{:.4} deg", value.to_degrees()),
            Quantity::Dimensionless => format!("{value:.4}"),
            Quantity::Mass => format!("{value:.3} kg"),
            q => format!("{value:.3e} {}", q.si_unit()),
        }
    }

    /// The factor from SI to the unit people read values of this quantity in, and that unit:
    /// mm for lengths, degrees for angles, SI otherwise (as reports show parameters).
    pub fn display_unit(&self) -> (f64, &'static str) {
        match self {
            Quantity::Length => (1e3, "mm"),
            Quantity::Angle => (180.0 / std::f64::consts::PI, "deg"),
            q => (1.0, q.si_unit()),
        }
    }

    /// The SI unit symbol.
    pub fn si_unit(&self) -> &'static str {
        match self {
            Quantity::Length => "m",
            Quantity::Angle => "rad",
            Quantity::Dimensionless => "1",
            Quantity::Compliance => "rad/(N m)",
            Quantity::Mass => "kg",
            Quantity::Rigidity => "N m^2",
            Quantity::PerKelvin => "1/K",
            Quantity::Other(u) => u,
        }
    }

    /// The magnitude (SI) no parameter of this quantity can physically have, with it in
    /// words: a value beyond is a typo or a unit mix-up, and would overflow the arithmetic
    /// it goes into. `None` where any magnitude can be meant (ratios, rigidities).
    pub fn absurd_beyond(&self) -> Option<(f64, &'static str)> {
        match self {
            // No arm's link, offset or eccentricity is a kilometre.
            Quantity::Length => Some((1e3, "1 km")),
            // Sixteen turns: no angle offset of a joint or frame.
            Quantity::Angle => Some((100.0, "100 rad")),
            // A radian under one newton-metre: a loose hinge, not a driven joint.
            Quantity::Compliance => Some((1.0, "1 rad/(N m)")),
            Quantity::Mass => Some((1e6, "1000 t")),
            // Ten percent a kelvin: no solid expands so.
            Quantity::PerKelvin => Some((0.1, "0.1 1/K")),
            Quantity::Dimensionless | Quantity::Rigidity | Quantity::Other(_) => None,
        }
    }
}

/// One identifiable parameter of a chain, an error model or the measurement setup.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ParamInfo {
    /// Stable dotted name, e.g. `j3.theta` or `joint_compliance.j2`.
    pub name: String,
    /// What it measures; the value is in the quantity's SI unit.
    pub quantity: Quantity,
    /// The value the robot file gives (SI).
    pub nominal: f64,
    /// Prior standard deviation (SI) used to regularise identification; `f64::INFINITY` for none.
    pub sigma: f64,
    /// Smallest physically meaningful value (SI); `-f64::INFINITY` for none.
    pub lower: f64,
    /// Largest physically meaningful value (SI); `f64::INFINITY` for none.
    pub upper: f64,
    /// Whether the fit's cost may have several minima along this parameter (a backlash that
    /// flips with the load's sign, a scale of a stiffness): calibration's restarts move it by
    /// its typical size, not only by its prior.
    pub multimodal: bool,
    /// The range (SI) in which a value is physically plausible for the model, as its plugin
    /// states it; values outside are reported, not refused. Unbounded when nothing is stated.
    pub plausible: (f64, f64),
}

impl ParamInfo {
    /// A parameter with a prior and no bounds.
    pub fn new(name: impl Into<String>, quantity: Quantity, nominal: f64, sigma: f64) -> Self {
        ParamInfo {
            name: name.into(),
            quantity,
            nominal,
            sigma,
            lower: f64::NEG_INFINITY,
            upper: f64::INFINITY,
            multimodal: false,
            plausible: (f64::NEG_INFINITY, f64::INFINITY),
        }
    }

    /// The same parameter marked as one along which the cost may have several minima.
    pub fn multimodal(mut self) -> Self {
        self.multimodal = true;
        self
    }

    /// The same parameter with the range `[lower, upper]` (SI) its model calls plausible.
    pub fn with_plausible(mut self, lower: f64, upper: f64) -> Self {
        self.plausible = (lower, upper);
        self
    }

    /// Whether `value` (SI) lies in the plausible range.
    pub fn is_plausible(&self, value: f64) -> bool {
        (self.plausible.0..=self.plausible.1).contains(&value)
    }

    /// "`name` = value is outside its plausible range [lo, hi] unit", in the unit people
    /// read, when `value` (SI) is outside; `None` otherwise.
    pub fn implausibility(&self, value: f64) -> Option<String> {
        if self.is_plausible(value) {
            return None;
        }
        let (lo, hi) = self.plausible;
        let bound = |v: f64| {
            if v.is_finite() {
                self.quantity.readable(v)
            } else {
                format!("{}∞", if v < 0.0 { "-" } else { "" })
            }
        };
        Some(format!(
            "{} = {} is outside the range its model calls plausible, {} to {}",
            self.name,
            self.quantity.readable(value),
            bound(lo),
            bound(hi)
        ))
    }

    /// Why `value` (SI) cannot be this parameter's, when it cannot: outside the bounds its
    /// model sets, or beyond what its quantity can physically be; `None` otherwise.
    pub fn absurdity(&self, value: f64) -> Option<String> {
        if let Some((bound, words)) = self.quantity.absurd_beyond()
            && value.abs() > bound
        {
            return Some(format!(
                "`{}` = {value:.3e} {} is physically absurd; expected a magnitude of at most {words}",
                self.name,
                self.quantity.si_unit()
            ));
        }
        if !(self.lower..=self.upper).contains(&value) {
            return Some(format!(
                "`{}` = {} is outside the range its model allows, {} to {}",
                self.name,
                self.quantity.readable(value),
                self.quantity.readable(self.lower),
                self.quantity.readable(self.upper)
            ));
        }
        None
    }

    /// The same parameter restricted to `[lower, upper]` (SI), which calibration respects.
    pub fn with_bounds(mut self, lower: f64, upper: f64) -> Self {
        self.lower = lower;
        self.upper = upper;
        self
    }
}

/// Whether parameter `name` is `pattern`, or matches it when it has `*` wildcards.
pub fn name_matches(pattern: &str, name: &str) -> bool {
    pattern == name || (pattern.contains('*') && glob_match(pattern, name))
}

/// `*` matches any run of characters (`pattern` has at least one); everything else matches
/// itself.
fn glob_match(pattern: &str, name: &str) -> bool {
    let parts: Vec<&str> = pattern.split('*').collect();
    let (first, last) = (parts[0], parts[parts.len() - 1]);
    if !name.starts_with(first) || name.len() < first.len() + last.len() || !name.ends_with(last) {
        return false;
    }
    let mut rest = &name[first.len()..name.len() - last.len()];
    for part in &parts[1..parts.len() - 1] {
        match rest.find(part) {
            Some(i) => rest = &rest[i + part.len()..],
            None => return false,
        }
    }
    true
}
