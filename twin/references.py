"""The bibliography the code and docs cite by short key (`[Yellowfish-TR eq. 27]`), and the
published figures the twin is checked against, each with its source.

The figures are reference data for validation, not parameters: the twin's parameters live in
twin/model/*.json and twin/model/*.xml only.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Source:
    """A document the code cites: who wrote it, what, where, when (None where the document
    does not say and no public record was found)."""

    key: str
    title: str
    authors: str | None
    published: str
    year: int | None

    def citation(self) -> str:
        who = self.authors or "authors not named in the document"
        return f"{who}: {self.title}. {self.published}" + (f", {self.year}" if self.year else "") + "."


def _bib(*sources: Source) -> dict[str, Source]:
    return {s.key: s for s in sources}


BIBLIOGRAPHY = _bib(
    Source("Yellowfish-TR", "The Yellowfish ASV: technical description, modelling and identification (technical "
           "report)", None, "Universidad Loyola Andalucía, research line ASV4Sustainability (Optimization and "
           "Control of Distributed Systems group)", None),
    Source("Bertoni-2024", "Autonomous Marine Surface Vessel Model (Simulink model with CyberShip I parameters)",
           "Simone Bertoni", "Simone Bertoni Control Lab, github.com/simorxb/autonomous-marine-surface-vessel-model",
           2024),
    Source("Relay-ISO", "Identification by self-oscillations (IS-O) of a small-scale tanker model in surge, sway "
           "and yaw, and I-PD dynamic-positioning controllers tuned from it", None,
           "University of Zagreb (experiments on lake Jarun)", None),
    Source("Morel-2024", "Practical identification approach for the actuation dynamics of autonomous surface "
           "vehicles with minimal instrumentation", "Thalia Morel, Luis Orihuela, Christophe Combastel, "
           "Guillermo Bejarano", "Ocean Engineering; extended version arXiv:2410.00631", 2024),
    Source("MMG-2015", "Introduction of MMG standard method for ship maneuvering predictions",
           "Hironori Yasukawa, Yasuo Yoshimura", "Journal of Marine Science and Technology 20, 37-52", 2015),
    Source("Fujiwara-1998", "Estimation of wind forces and moments acting on ships",
           "Toshifumi Fujiwara, Michio Ueno, Tadashi Nimura", "Journal of the Society of Naval Architects of "
           "Japan 183, 77-90", 1998),
    Source("Fossen-2021", "Handbook of Marine Craft Hydrodynamics and Motion Control, 2nd edition",
           "Thor I. Fossen", "John Wiley & Sons", 2021),
    Source("ESSO-FRT", "Free-running model tests of the VLCC Esso Osaka with on-board anemometer (data set "
           "FRT-DS-ESSO)", "NAOE 5th laboratory, Osaka University", "github.com/NAOE-5thLab/FRT-DS-ESSO; used in "
           "Wakita et al., J. Mar. Sci. Technol. (2022), doi 10.1007/s00773-021-00867-1", 2022),
    Source("BlueBoat-SI", "BlueBoat system identification recordings", "Jan Kristian Andersen",
           "github.com/jankristia/BlueBoatSystemIdentification", None),
    Source("Fossen-2011", "Handbook of Marine Craft Hydrodynamics and Motion Control, 1st edition",
           "Thor I. Fossen", "John Wiley & Sons", 2011),
    Source("NAOE-MMG-SIM", "MMG model simulator for a one-propeller one-rudder ship, with the Esso Osaka model's "
           "coefficient files", "NAOE 5th laboratory, Osaka University",
           "github.com/NAOE-5thLab/mmg-1p1r-simulator", None),
    Source("RTS-1965", "Maximum likelihood estimates of linear dynamic systems",
           "Herbert E. Rauch, F. Tung, Charlotte T. Striebel", "AIAA Journal 3(8), 1445-1450", 1965),
    Source("Ljung-1999", "System Identification: Theory for the User, 2nd edition (section 7.3: prediction-error "
           "criteria for several outputs, maximum likelihood with the noise's covariance unknown)", "Lennart Ljung",
           "Prentice Hall, Upper Saddle River NJ", 1999),
    Source("Savitzky-1964", "Smoothing and differentiation of data by simplified least squares procedures",
           "Abraham Savitzky, Marcel J. E. Golay", "Analytical Chemistry 36(8), 1627-1639", 1964),
    Source("Wilcoxon-1945", "Individual comparisons by ranking methods", "Frank Wilcoxon",
           "Biometrics Bulletin 1(6), 80-83", 1945),
    Source("Atkinson-Fedorov-1975", "The design of experiments for discriminating between two rival models",
           "A. C. Atkinson, V. V. Fedorov", "Biometrika 62(1), 57-70", 1975),
    Source("BlueRobotics-T200", "T200 thruster: technical details and performance charts", "Blue Robotics",
           "bluerobotics.com, T200 product page and its performance data", None),
    Source("ArduPilot-SITL", "SITL JSON physics backend interface (libraries/SITL/SIM_JSON.h, SIM_JSON.cpp, "
           "examples/JSON/readme.md)", "ArduPilot development team", "github.com/ArduPilot/ardupilot", None),
    Source("Ray-init", "ray.init: the address argument (\"auto\": RAY_ADDRESS, else the cluster `ray start` "
           "recorded in /tmp/ray/ray_current_cluster); ray._private.services.get_ray_address_from_environment",
           "Ray developers (Anyscale)", "docs.ray.io and github.com/ray-project/ray", None),
    Source("RFC-7540", "Hypertext Transfer Protocol Version 2 (HTTP/2), RFC 7540", "M. Belshe, R. Peon, "
           "M. Thomson (ed.)", "IETF", 2015),
    Source("CyberShip-I", "CyberShip I, a 1:70 model of a supply ship (Marine Cybernetics Laboratory, NTNU): total "
           "inertia and linear damping as used by [Bertoni-2024]", None, "Norwegian University of Science and "
           "Technology; no primary publication of these parameter values was located, so they are cited through "
           "[Bertoni-2024]", None),
    Source("Wakita-2022", "On neural network identification for low-speed ship maneuvering model",
           "Kouki Wakita, Atsuo Maki, Naoya Umeda, Yoshiki Miyauchi, Tohga Shimoji, Dimas M. Rachman, "
           "Youhei Akimoto", "Journal of Marine Science and Technology 27, 772-785, doi 10.1007/s00773-021-00867-1",
           2022),
    Source("Miyauchi-2022", "System parameter exploration of ship maneuvering model for automatic docking/berthing "
           "using CMA-ES", "Yoshiki Miyauchi, Atsuo Maki, Naoya Umeda, Dimas M. Rachman, Youhei Akimoto",
           "Journal of Marine Science and Technology 27, 1065-1083", 2022),
    Source("Kijima-1990", "On the manoeuvring performance of a ship with the parameter of loading condition",
           "Katsuro Kijima, Toshiyuki Katsuno, Yasuaki Nakiri, Yoshitaka Furukawa",
           "Journal of the Society of Naval Architects of Japan 168, 141-148", 1990),
    Source("Blendermann-1994", "Parameter identification of wind loads on ships", "Werner Blendermann",
           "Journal of Wind Engineering and Industrial Aerodynamics 51(3), 339-351", 1994),
    Source("ArduPilot-INS", "The inertial sensor library (libraries/AP_InertialSensor: the gyro the IMU log message "
           "and the AHRS's rates give is get_gyro(), after the two-pole low-pass LowPassFilter2p at INS_GYRO_FILTER "
           "Hz, and an optional harmonic notch, INS_HNTCH_ENABLE)", "ArduPilot development team",
           "github.com/ArduPilot/ardupilot; ardupilot.org, IMU notch and low-pass filtering", None),
    Source("ArduPilot-GPS", "The GPS library (libraries/AP_GPS: GPS_DELAY_MS, GPS1_DELAY_MS, the delay the EKF "
           "compensates for; 0 takes the driver's, AP_GPS_UBLOX::get_lag, 0.12 s for a u-blox 7, M8, M9, M10 or F9 "
           "and 0.22 s for older ones; SITL's SIM_GPS1_LAG_MS)", "ArduPilot development team",
           "github.com/ArduPilot/ardupilot", None),
    Source("ArduPilot-CompassMot", "Compass motor interference compensation (COMPASS_MOT_TYPE, COMPASS_MOT_X/Y/Z)",
           "ArduPilot development team", "ArduPilot documentation, ardupilot.org", None),
    Source("ArduPilot-Rover", "Rover parameters (FRAME_CLASS, SERVOn_FUNCTION, CRUISE_SPEED, CRUISE_THROTTLE, "
           "WP_SPEED, ATC_STR_RAT_*, ATC_SPEED_*) and the default Rover SITL parameter files "
           "(Tools/autotest/default_params/rover.parm, rover-skid.parm)", "ArduPilot development team",
           "github.com/ArduPilot/ardupilot; ardupilot.org/rover", None),
    Source("BlueRobotics-BasicESC", "Basic ESC documentation (BESC30-R3, BLHeli_S firmware): quick start (a stopped "
           "signal of 1500 µs for a few seconds initialises the ESC) and pulse-width signal table (deadband ±25 µs)",
           "Blue Robotics", "docs.bluerobotics.com/bescr3; source github.com/bluerobotics/bluerobotics.github.io, "
           "bescr3/index.md", None),
    Source("ITTC-1957", "Skin friction and turbulence stimulation (the ITTC-1957 model-ship correlation line, "
           "C_F = 0.075/(log10 Re − 2)²)", "International Towing Tank Conference",
           "Proceedings of the 8th ITTC, Madrid; ITTC Recommended Procedure 7.5-02-02-02", 1957),
    Source("ITTC-2011", "Fresh water and seawater properties", "International Towing Tank Conference",
           "ITTC Recommended Procedure 7.5-02-01-03", 2011),
    Source("IMO-MSC137", "Standards for ship manoeuvrability (turning circle, zig-zag and stopping tests, each "
           "begun from a steady approach at the test speed)", "International Maritime Organization",
           "Resolution MSC.137(76), with the explanatory notes MSC/Circ.1053", 2002),
    Source("Clarke-1983", "The application of manoeuvring criteria in hull design using linear theory",
           "D. Clarke, P. Gedling, G. Hine", "Transactions of the Royal Institution of Naval Architects 125, 45-68",
           1983),
    Source("Glauert-1935", "Airplane propellers (momentum and blade-element theory of a propeller, including its "
           "normal force in oblique flow)", "Hermann Glauert", "in W. F. Durand (ed.), Aerodynamic Theory, vol. IV, "
           "Division L, Springer, Berlin", 1935),
    Source("Newman-1977", "Marine Hydrodynamics (chapter 4: added mass of sections; chapter 6: wave loads and the Haskind "
           "relations; chapter 7: slender-body theory of lifting bodies)",
           "J. N. Newman", "MIT Press, Cambridge MA", 1977),
    Source("Hoerner-1965", "Fluid-Dynamic Drag (two-dimensional drag of bluff sections)", "Sighard F. Hoerner",
           "published by the author, Midland Park NJ", 1965),
    Source("Holtrop-1982", "An approximate power prediction method", "J. Holtrop, G. G. J. Mennen",
           "International Shipbuilding Progress 29(335), 166-170", 1982),
    Source("BlueRobotics-BlueBoat", "BlueBoat: technical details (dimensions, mass, maximum speed 3.0 m/s with two "
           "batteries)", "Blue Robotics", "bluerobotics.com, BlueBoat product page and its discussion forum", None),
    Source("Faltinsen-1990", "Sea Loads on Ships and Offshore Structures", "Odd M. Faltinsen",
           "Cambridge University Press", 1990),
    Source("DNV-RP-C205", "Environmental Conditions and Environmental Loads (Recommended Practice DNV-RP-C205)",
           "Det Norske Veritas", "DNV, Høvik; the 2010 edition and its revisions", 2010),
    Source("Journee-Massie-2001", "Offshore Hydromechanics, first edition", "J. M. J. Journée, W. W. Massie",
           "Delft University of Technology", 2001),
    Source("Lewis-1929", "The inertia of the water surrounding a vibrating ship", "Frank M. Lewis",
           "Transactions of the Society of Naval Architects and Marine Engineers 37, 1-20", 1929),
    Source("Cummins-1962", "The impulse response function and ship motions", "W. E. Cummins",
           "Schiffstechnik 9, 101-109", 1962),
    Source("Newman-1974", "Second-order, slowly-varying forces on vessels in irregular waves", "J. N. Newman",
           "Proceedings of the International Symposium on the Dynamics of Marine Vehicles and Structures in Waves, "
           "University College London, 182-186", 1974),
    Source("Maruo-1960", "The drift of a body floating on waves", "Hajime Maruo", "Journal of Ship Research 4, 1-10",
           1960),
    Source("Ursell-1947", "The effect of a fixed vertical barrier on surface waves in deep water", "F. Ursell",
           "Proceedings of the Cambridge Philosophical Society 43, 374-382", 1947),
    Source("Stokes-1847", "On the theory of oscillatory waves (the mean drift of a particle under a progressive "
           "wave)", "G. G. Stokes", "Transactions of the Cambridge Philosophical Society 8, 441-455", 1847),
    Source("Michell-1893", "The highest waves in water", "J. H. Michell", "Philosophical Magazine 36, 430-437", 1893),
    Source("Frank-1967", "Oscillation of cylinders in or below the free surface of deep fluids (the close-fit "
           "source method for ship sections)", "W. Frank", "Naval Ship Research and Development Center, Report 2375",
           1967),
    Source("Wehausen-Laitone-1960", "Surface waves (the pulsating source below a free surface in two dimensions)",
           "J. V. Wehausen, E. V. Laitone", "Handbuch der Physik IX, Springer, 446-778", 1960),
    Source("Ursell-1949", "On the heaving motion of a circular cylinder on the surface of a fluid", "F. Ursell",
           "Quarterly Journal of Mechanics and Applied Mathematics 2, 218-231", 1949),
    Source("Wheeler-1970", "Method for calculating forces produced by irregular waves (the stretching of linear "
           "wave kinematics to the instantaneous surface)", "J. D. Wheeler",
           "Journal of Petroleum Technology 22(3), 359-367", 1970),
)

def markdown() -> str:
    """docs/bibliography.md: every source by key, as the code and the docs cite it."""
    lines = ["# Bibliography", "", "Every source the code and these pages cite, by the key they cite it with "
             "(`[Yellowfish-TR eq. 27]`). Generated from `twin/references.py` "
             "(`python -m twin.references > docs/bibliography.md`); a test checks the two agree.", ""]
    for key in sorted(BIBLIOGRAPHY, key=str.lower):
        lines += [f"- **{key}**: {BIBLIOGRAPHY[key].citation()}"]
    return "\n".join(lines) + "\n"


# [Yellowfish-TR], by mass case.
YELLOWFISH_TR = {
    # Table III: mass distribution (kg)
    "metal_bars_kg": {"min": 2.31, "nominal": 2.31, "max": 2.31},
    "hulls_kg": {"min": 16.12, "nominal": 16.12, "max": 16.12},
    "electronics_box_kg": {"min": 3.10, "nominal": 3.56, "max": 4.30},
    "sensors_kg": {"min": 0.20, "nominal": 0.40, "max": 1.00},
    "battery_kg": {"min": 2.00, "nominal": 2.00, "max": 2.00},
    "m_kg": {"min": 23.73, "nominal": 24.39, "max": 25.73},
    # Table IV: centre of gravity (mm, kg)
    "x_hull_mm": {"min": -22.0, "nominal": -22.0, "max": -22.0},
    "m_hull_kg": {"min": 8.06, "nominal": 8.06, "max": 8.06},
    "x_box_mm": {"min": -12.0, "nominal": -15.0, "max": -18.0},
    "m_box_kg": {"min": 7.61, "nominal": 8.27, "max": 9.61},
    "xg_mm": {"min": -18.7, "nominal": -19.6, "max": -20.5},
    # Table V: yaw inertia (m, kg m²); Ibox is printed for the nominal column only
    "a_box_m": 0.50,
    "b_box_m": 0.52,
    "I_box_kgm2": 0.3586,
    "d_g_m": {"min": 0.21, "nominal": 0.30, "max": 0.39},
    "Iz_kgm2": {"min": 1.07, "nominal": 1.81, "max": 2.81},
    # Table VI: ellipsoid added mass (semi-axes in m)
    "a_m": {"min": 0.511, "nominal": 0.560, "max": 0.590},
    "b_m": {"min": 0.105, "nominal": 0.1275, "max": 0.135},
    "c_m": {"min": 0.030, "nominal": 0.050, "max": 0.070},
    "alpha0": {"min": 0.0345, "nominal": 0.0827, "max": 0.1011},
    "beta0": {"min": 0.3433, "nominal": 0.6454, "max": 0.7668},
    "y_m_m": 0.675,
    "Xudot_kg": {"min": -2.15, "nominal": -1.00, "max": -0.27},
    "Yvdot_kg": {"min": -22.59, "nominal": -10.92, "max": -3.59},
    "Nrdot_kgm2": {"min": -4.35, "nominal": -3.95, "max": -3.74},
    # §V-B and Table VIII: actuation
    "d_thrusters_m": 0.68,
    "Fu_min_n": -45.32,
    "Fu_max_n": 57.40,
    "tau_r_max_nm": 17.46,
    "rho_water_kg_m3": 1000.0,  # reproduces Table VI's nominal Xu̇ and Yv̇
}

# [Bertoni-2024] (CyberShip I): total inertia and linear damping.
CYBERSHIP_I = {
    "M": [[26.4272, 0.0, 0.0], [0.0, 51.3671, -0.7372], [0.0, -0.7372, 1.2645]],
    "D": [[4.3411, 0.0, 0.0], [0.0, 6.2983, 0.0], [0.0, 0.0, 1.2577]],
    "d_thrusters_m": 0.4,
}


if __name__ == "__main__":
    print(markdown(), end="")
