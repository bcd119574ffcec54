//! The command line's names for the library's choices: each enum here mirrors one of
//! the library (the same variants, in kebab case on the command line) and converts
//! into it, so that the library's types do not depend on clap.

/// A command-line enum mirroring the library enum `$core`, variant for variant, with
/// `From` into it.
macro_rules! choice {
    ($(#[$m:meta])* $name:ident => $core:path { $($(#[$vm:meta])* $v:ident),+ $(,)? }) => {
        $(#[$m])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
        pub enum $name {
            $($(#[$vm])* $v),+
        }

        impl From<$name> for $core {
            fn from(c: $name) -> $core {
                match c {
                    $($name::$v => <$core>::$v),+
                }
            }
        }
    };
}

choice! {
    /// How the alternation starts ([`crate::estimator::Init`]).
    InitArg => crate::estimator::Init {
        /// Linear ARMA(p,q) by conditional least squares; b by Gauss-Newton in each b-step.
        Arma,
        /// The paper's literal scheme: AR(p) least squares, b = 0, b by one LS step.
        Literal,
    }
}

choice! {
    /// Which computation gives the local fits ([`crate::estimator::FitPath`]).
    FitPathArg => crate::estimator::FitPath {
        /// One-pass exact moment tables (every bandwidth of the ladder at once).
        Fast,
        /// KD-tree gather and dense least squares per grid point and bandwidth.
        Direct,
    }
}

choice! {
    /// What to do with NaN, infinite or missing values ([`crate::log::NanPolicy`]).
    NanArg => crate::log::NanPolicy {
        /// Fail with exit code 2, naming the column, the count and the first positions.
        Reject,
        /// Replace each by linear interpolation between its finite neighbours (in time).
        Interpolate,
    }
}

choice! {
    /// What to do with gaps or irregular sampling ([`crate::log::GapPolicy`]).
    GapArg => crate::log::GapPolicy {
        /// Fail with exit code 2, listing the first irregular intervals.
        Reject,
        /// Keep the samples; record uniformly sampled segments between the irregular intervals.
        Split,
        /// Resample every channel onto a uniform grid by linear interpolation.
        Interpolate,
    }
}

choice! {
    /// How rejected samples are replaced ([`crate::workflow::pauta::Replace`]).
    ReplaceArg => crate::workflow::pauta::Replace {
        /// Linear interpolation between the nearest kept samples in time.
        Interpolate,
        /// The mean of the kept samples.
        Mean,
        /// The previous kept sample (the first kept one at the start).
        Hold,
    }
}

choice! {
    /// The per-segment statistic ([`crate::workflow::stationarity::SegmentStat`]).
    SegmentStatArg => crate::workflow::stationarity::SegmentStat {
        Mean,
        MeanSquare,
    }
}

choice! {
    /// What to do when the stationarity test rejects ([`crate::workflow::prep::Nonstationary`]).
    NonstationaryArg => crate::workflow::prep::Nonstationary {
        /// Remove the least-squares linear trend.
        Trend,
        /// First differences x_t - x_{t-1}.
        Diff,
        /// Record the rejection, change nothing.
        None,
    }
}
