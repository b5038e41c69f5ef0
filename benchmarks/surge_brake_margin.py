"""Whether a plant can stop its cruise in time at all, and whether a fitted config still stops on the weakest
reverse thrust its fit allows: the measurements behind docs/calibrate-flight.md, session 17, branch i13heavy.

    PYTHONPATH=. python3 benchmarks/surge_brake_margin.py physics [--plants 50]
    PYTHONPATH=. python3 benchmarks/surge_brake_margin.py weak-reverse corner-MtdL corner-Mtdl ...

``physics``: on each plant's true physics (no drafts, the body held at 1.5 m), from a steady cruise at 0.15 m/s
both horizontal motors at full reverse (-0.9, the mixer's ``max_output``, and -1.0) from t = 0: time to under
5 cm/s, and the fastest cruise full reverse stops within 1.0 s. Pure physics, no controller: under a second of CPU.

``weak-reverse``: calibrate each named plant of ``plant_set(50)``, then fly the safety flight with the fitted config
on the plant made as weak in reverse as the fit's 3-sigma box allows (true reverse thrust per surge mass = fitted
/ U^3), for three shares of the fitted brake the speed cap may count on before a brake in flight: 1 (the point
estimate), min(1, 1 / (BRAKE_SHARE U^3)) and 1/U (session 17), each on ``BRAKE_SHARE``, then the rule shipped since
session 20 (``measured_brake``: the calibration's measured brake, 3 sigma low, on ``MEASURED_BRAKE_SHARE``); and the
cruise on the true plant. About 70 s of CPU a plant.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace

import feelium.flight.estimators as estimators
from feelium.daemon.config import Config
from feelium.flight.loops import BRAKE_SHARE
from feelium.lab.flight.calibrate import calibrate_sim, tight_goals
from feelium.lab.flight.plants import Plant, plant_set
from feelium.lab.flight.safety import safety_flight
from feelium.lab.flight.stoppable import fastest_stoppable, stop_time

SHARES = {"point": lambda u: 1.0, "brake_share_box": lambda u: min(1.0, 1.0 / (BRAKE_SHARE * u**3)), "inverse_u": lambda u: 1.0 / u}


def weak_reverse(name: str) -> dict[str, object]:
    plant = {p.name: p for p in plant_set(50)}[name]
    measured, blimp = calibrate_sim(Config().flight, plant.blimp).config, plant.blimp
    fitted = replace(measured, surge_brake_shown=0.0)  # the shares below replace the calibration's measured brake
    u = fitted.surge_uncertainty
    reverse_per_mass = fitted.horizontal_thrust_n * fitted.horizontal_reverse_ratio / fitted.mass_kg / u**3
    ratio = reverse_per_mass * blimp.inertial_mass_kg * blimp.surge_mass_factor / blimp.horizontal_motor.max_thrust_n
    weak = Plant(name + "-weak-reverse", replace(blimp, horizontal_motor=replace(blimp.horizontal_motor, reverse_ratio=ratio)), plant.factors)
    row: dict[str, object] = {"plant": name, "surge_U": u, "reverse_ratio": blimp.horizontal_motor.reverse_ratio, "weak": round(ratio, 4)}
    shipped = estimators.SurgeEstimate.__init__
    for label, share in SHARES.items():
        def init(self: estimators.SurgeEstimate, config: object, share=share) -> None:  # type: ignore[no-untyped-def]
            shipped(self, config)
            self.effectiveness.shown_by_side = [share(u), share(u)]
        estimators.SurgeEstimate.__init__ = init  # type: ignore[method-assign]
        try:
            result = safety_flight(fitted, weak)
            row[label] = {"stop_s": round(result.stop_s, 3), "failures": result.failures(),
                          "cruise_true_plant": round(tight_goals(fitted, blimp)["cruise_fraction"], 3)}
        finally:
            estimators.SurgeEstimate.__init__ = shipped  # type: ignore[method-assign]
    result = safety_flight(measured, weak)  # session 20: the measured brake, 3 sigma low, on 0.8 of the authority
    row["measured_brake"] = {"surge_brake_shown": measured.surge_brake_shown, "stop_s": round(result.stop_s, 3),
                             "failures": result.failures(), "cruise_true_plant": round(tight_goals(measured, blimp)["cruise_fraction"], 3)}
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("what", choices=("physics", "weak-reverse"))
    parser.add_argument("plants", nargs="*")
    parser.add_argument("--plants", dest="count", type=int, default=50)
    args = parser.parse_args()
    if args.what == "weak-reverse":
        for name in args.plants:
            print(json.dumps(weak_reverse(name)))
        return
    for plant in plant_set(args.count):
        b = plant.blimp
        print(json.dumps({"plant": plant.name, "stop_from_0.15_s": [round(stop_time(b, 0.15, c, dt=0.001), 3) for c in (-0.9, -1.0)],
                          "fastest_stoppable_m_s": [round(fastest_stoppable(b, c, dt=0.001, high_m_s=0.5, iterations=30), 3) for c in (-0.9, -1.0)]}))


if __name__ == "__main__":
    main()
