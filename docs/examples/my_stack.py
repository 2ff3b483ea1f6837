"""An example controller: keeps the speed limit (braking for a lower one ahead) and its
distance to the car ahead, and stops at red and yellow lights."""


def control(obs: dict) -> dict:
    speed = obs["speed"]
    accel = min(2.0, obs["speed_limit"] - speed)           # towards the speed limit
    ahead = obs["next_speed_limit"]                        # brake for a lower limit ahead
    if ahead and ahead["limit"] < speed:
        accel = min(accel, (ahead["limit"] ** 2 - speed**2) / max(2 * ahead["distance"], 1.0))
    leader = obs["leader"]                                 # keep 2 s and 5 m to the car ahead
    if leader is not None:
        accel = min(accel, (leader["gap"] - 5.0 - 2.0 * speed) / 2.0)
    signal = obs["next_signal"]                            # stop before a red or yellow light
    if signal is not None and signal["state"] in "rRyu":
        stop_in = signal["distance"] - 2.0
        if stop_in < speed * speed / 6.0 + speed:          # could not stop later at 3 m/s²
            accel = min(accel, -speed * speed / max(2 * stop_in, 0.5))
    return {"acceleration": max(-6.0, accel)}
