//! The transverse Mercator projection of an ellipsoid, forward: Krüger's series in the third
//! flattening to order six, as Karney (2011, "Transverse Mercator with an accuracy of a few
//! nanometers", J. Geodesy 85) gives it. Within a UTM zone (and well beyond) it is exact to
//! far below a millimetre.

/// An ellipsoid by its semi-major axis and flattening.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ellipsoid {
    /// Semi-major axis, metres.
    pub a: f64,
    /// Flattening.
    pub f: f64,
}

/// WGS 84's ellipsoid.
pub const WGS84: Ellipsoid = Ellipsoid {
    a: 6_378_137.0,
    f: 1.0 / 298.257_223_563,
};

/// GRS 80's ellipsoid (NAD83's and ETRS89's): its flattening differs from WGS 84's in the
/// ninth digit.
pub const GRS80: Ellipsoid = Ellipsoid {
    a: 6_378_137.0,
    f: 1.0 / 298.257_222_101,
};

/// A point projected: map coordinates and the meridian convergence there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Projected {
    /// Metres east of the central meridian, scaled by the central scale factor.
    pub x: f64,
    /// Metres north of the equator along the projection, scaled the same.
    pub y: f64,
    /// The bearing of grid north, radians clockwise from true north.
    pub convergence: f64,
}

/// The transverse Mercator of one ellipsoid, with its series' coefficients computed once.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TransverseMercator {
    /// First eccentricity.
    e: f64,
    /// The rectifying radius times the central scale factor: metres per radian of `xi`.
    scale: f64,
    /// Krüger's alpha_1 ..= alpha_6.
    alpha: [f64; 6],
}

impl TransverseMercator {
    /// The projection of `ellipsoid` with central scale factor `k0`.
    pub fn new(ellipsoid: Ellipsoid, k0: f64) -> TransverseMercator {
        let f = ellipsoid.f;
        let n = f / (2.0 - f);
        let (n2, n3) = (n * n, n * n * n);
        let (n4, n5, n6) = (n2 * n2, n2 * n3, n3 * n3);
        let rectifying = ellipsoid.a / (1.0 + n) * (1.0 + n2 / 4.0 + n4 / 64.0 + n6 / 256.0);
        let alpha = [
            n / 2.0 - 2.0 * n2 / 3.0 + 5.0 * n3 / 16.0 + 41.0 * n4 / 180.0 - 127.0 * n5 / 288.0
                + 7891.0 * n6 / 37800.0,
            13.0 * n2 / 48.0 - 3.0 * n3 / 5.0 + 557.0 * n4 / 1440.0 + 281.0 * n5 / 630.0
                - 1_983_433.0 * n6 / 1_935_360.0,
            61.0 * n3 / 240.0 - 103.0 * n4 / 140.0
                + 15061.0 * n5 / 26880.0
                + 167_603.0 * n6 / 181_440.0,
            49561.0 * n4 / 161_280.0 - 179.0 * n5 / 168.0 + 6_601_661.0 * n6 / 7_257_600.0,
            34729.0 * n5 / 80640.0 - 3_418_889.0 * n6 / 1_995_840.0,
            212_378_941.0 * n6 / 319_334_400.0,
        ];
        TransverseMercator {
            e: (f * (2.0 - f)).sqrt(),
            scale: k0 * rectifying,
            alpha,
        }
    }

    /// Projects latitude `phi` and longitude `lambda` from the central meridian, radians
    /// (`|lambda| < pi / 2`, `|phi| < pi / 2`).
    pub fn forward(&self, phi: f64, lambda: f64) -> Projected {
        let e = self.e;
        let sin_phi = phi.sin();
        // The tangent of the conformal latitude.
        let t = (sin_phi.atanh() - e * (e * sin_phi).atanh()).sinh();
        let (sin_l, cos_l) = lambda.sin_cos();
        let root = (1.0 + t * t).sqrt();
        let xi0 = t.atan2(cos_l);
        let eta0 = (sin_l / root).atanh();
        let (mut xi, mut eta) = (xi0, eta0);
        let (mut p, mut q) = (1.0, 0.0);
        for (k, a) in self.alpha.iter().enumerate() {
            let j = 2.0 * (k + 1) as f64;
            let (s, c) = (j * xi0).sin_cos();
            let (sh, ch) = ((j * eta0).sinh(), (j * eta0).cosh());
            xi += a * s * ch;
            eta += a * c * sh;
            p += j * a * c * ch;
            q += j * a * s * sh;
        }
        let convergence = (t * sin_l).atan2(root * cos_l) + q.atan2(p);
        Projected {
            x: self.scale * eta,
            y: self.scale * xi,
            convergence,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The classic series for a meridian's arc from the equator (Helmert's, in the third
    /// flattening), independent of Krüger's.
    fn meridian_arc(ellipsoid: Ellipsoid, phi: f64) -> f64 {
        let n = ellipsoid.f / (2.0 - ellipsoid.f);
        let (n2, n3, n4) = (n * n, n * n * n, n * n * n * n);
        ellipsoid.a / (1.0 + n)
            * ((1.0 + n2 / 4.0 + n4 / 64.0) * phi - 1.5 * (n - n3 / 8.0) * (2.0 * phi).sin()
                + 15.0 / 16.0 * (n2 - n4 / 4.0) * (4.0 * phi).sin()
                - 35.0 / 48.0 * n3 * (6.0 * phi).sin()
                + 315.0 / 512.0 * n4 * (8.0 * phi).sin())
    }

    #[test]
    fn on_the_central_meridian_northing_is_the_scaled_meridian_arc() {
        let tm = TransverseMercator::new(WGS84, 0.9996);
        for degrees in [0.0f64, 10.0, 45.0, 60.0, 80.0, -33.0] {
            let p = tm.forward(degrees.to_radians(), 0.0);
            let expected = 0.9996 * meridian_arc(WGS84, degrees.to_radians());
            assert!(
                (p.y - expected).abs() < 1e-4,
                "{degrees}: {} {expected}",
                p.y
            );
            assert_eq!((p.x, p.convergence), (0.0, 0.0));
        }
        // The published WGS 84 meridian arc to 45 degrees: 4 984 944.378 m.
        let p = tm.forward(45f64.to_radians(), 0.0);
        assert!((p.y / 0.9996 - 4_984_944.378).abs() < 1e-3, "{}", p.y);
    }

    #[test]
    fn snyders_worked_example_on_clarke_1866() {
        // Snyder, "Map Projections: A Working Manual" (USGS PP 1395), p. 269: Clarke 1866,
        // 40°30' N, 73°30' W on the central meridian 75° W, k0 = 0.9996:
        // x = 127 106.5 m, y = 4 484 124.4 m.
        let clarke = Ellipsoid {
            a: 6_378_206.4,
            f: 1.0 / 294.978_698_2,
        };
        let tm = TransverseMercator::new(clarke, 0.9996);
        let p = tm.forward(40.5f64.to_radians(), 1.5f64.to_radians());
        assert!((p.x - 127_106.5).abs() < 0.06, "{}", p.x);
        assert!((p.y - 4_484_124.4).abs() < 0.06, "{}", p.y);
    }

    #[test]
    fn convergence_is_longitude_times_sine_latitude_near_the_meridian() {
        let tm = TransverseMercator::new(WGS84, 0.9996);
        let (phi, lambda) = (47f64.to_radians(), 0.01f64.to_radians());
        let p = tm.forward(phi, lambda);
        assert!((p.convergence - lambda * phi.sin()).abs() < 1e-9);
        let west = tm.forward(-phi, -lambda);
        assert!((west.convergence - p.convergence).abs() < 1e-15);
        assert!((west.x + p.x).abs() < 1e-9 && (west.y + p.y).abs() < 1e-9);
    }

    #[test]
    fn matches_redfearns_series_to_a_millimetre_across_a_zone() {
        // Redfearn's series (the Ordnance Survey's and Snyder's form), independent of Krüger's
        // and good to well under a millimetre within 3 degrees of the meridian.
        let (a, f, k0) = (WGS84.a, WGS84.f, 0.9996);
        let e2 = f * (2.0 - f);
        let ep2 = e2 / (1.0 - e2);
        let tm = TransverseMercator::new(WGS84, k0);
        for (lat, lon) in [
            (47.6, -2.9),
            (5.0, 2.5),
            (-37.8, 1.2),
            (61.3, 2.99),
            (0.5, -3.0),
        ] {
            let (phi, lambda) = (f64::to_radians(lat), f64::to_radians(lon));
            let nu = a / (1.0 - e2 * phi.sin().powi(2)).sqrt();
            let t = phi.tan().powi(2);
            let c = ep2 * phi.cos().powi(2);
            let aa = lambda * phi.cos();
            let m = meridian_arc(WGS84, phi);
            let x = k0
                * nu
                * (aa
                    + (1.0 - t + c) * aa.powi(3) / 6.0
                    + (5.0 - 18.0 * t + t * t + 72.0 * c - 58.0 * ep2) * aa.powi(5) / 120.0);
            let y = k0
                * (m + nu
                    * phi.tan()
                    * (aa * aa / 2.0
                        + (5.0 - t + 9.0 * c + 4.0 * c * c) * aa.powi(4) / 24.0
                        + (61.0 - 58.0 * t + t * t + 600.0 * c - 330.0 * ep2) * aa.powi(6)
                            / 720.0));
            let p = tm.forward(phi, lambda);
            assert!((p.x - x).abs() < 1e-3, "{lat} {lon}: x {} {x}", p.x);
            assert!((p.y - y).abs() < 1e-3, "{lat} {lon}: y {} {y}", p.y);
        }
    }
}
