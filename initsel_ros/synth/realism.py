"""Effect strengths: the ``--realism`` random mix, and named clean/default/strong levels.

``draw_realism(seed)`` draws one camera per sequence (domain randomization); the ranges are
the ``REALISM_RANGES`` table (also in ``docs/synth.md``). ``EFFECT_LEVELS`` names, per effect,
the parameters of its ``default`` (a common camera) and ``strong`` (a poor one) strength, for
robustness measurements.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from initsel_ros.camera import Intrinsics
from initsel_ros.errors import ConfigError
from initsel_ros.synth.effects import Effects

#: ``--realism`` ranges: effect -> (probability the effect is on, range drawn uniformly,
#: log-uniformly for full_well). Units as in :class:`Effects`.
REALISM_RANGES: dict[str, tuple[float, tuple[float, float]]] = {
    'exposure_time': (0.7, (0.002, 0.020)),  # s
    'line_delay': (0.5, (10e-6, 50e-6)),  # s per row (4.8-24 ms readout at 480 rows)
    'gain_ramp_from': (0.5, (0.6, 1.0)),  # gain; ramps up or down (coin flip)
    'gain_ramp_to': (0.5, (1.0, 1.5)),  # gain
    'gain_ramp_duration': (0.5, (0.5, 3.0)),  # s
    'gain_ramp_start': (0.5, (0.0, 1.5)),  # s after the first frame
    'exposure': (0.5, (0.03, 0.15)),  # relative amplitude
    'vignetting': (1.0, (0.0, 0.8)),  # fraction of cos^4
    'noise': (1.0, (0.5, 3.0)),  # read noise, grey levels
    'full_well': (0.8, (2500.0, 20000.0)),  # electrons (log-uniform)
    'jpeg_quality': (0.5, (60, 95)),  # JPEG quality
    'blur': (0.4, (0.3, 1.2)),  # defocus sigma, px
    'movers': (0.3, (1, 3)),  # moving boards
    'k1': (0.5, (-0.25, 0.15)),  # radial distortion
    'k2': (0.5, (-0.05, 0.05)),  # radial distortion (+ k1^2 / 2 when k1 < 0)
    'p': (0.5, (-1e-3, 1e-3)),  # tangential distortion p1, p2
}

#: Per effect, the ``Effects`` fields (and ``distortion`` / ``scene``) of its default and strong
#: strengths; ``clean`` is ``Effects()`` on the structure_texture scene.
EFFECT_LEVELS: dict[str, dict[str, dict[str, Any]]] = {
    'motion_blur': {'default': {'exposure_time': 0.010}, 'strong': {'exposure_time': 0.030}},
    'rolling_shutter': {'default': {'line_delay': 30e-6}, 'strong': {'line_delay': 60e-6}},
    'exposure_ramp': {
        'default': {'gain_ramp': (0.6, 1.4, 2.0)},
        'strong': {'gain_ramp': (0.4, 1.8, 1.0)},
    },
    'vignetting': {'default': {'vignetting': 0.5}, 'strong': {'vignetting': 1.0}},
    'noise': {
        'default': {'noise': 2.0, 'full_well': 10000.0},
        'strong': {'noise': 4.0, 'full_well': 2500.0},
    },
    'jpeg': {'default': {'jpeg_quality': 80}, 'strong': {'jpeg_quality': 40}},
    'distortion': {
        'default': {'distortion': (-0.15, 0.05, 5e-4, -5e-4)},
        'strong': {'distortion': (-0.28, 0.08, 1e-3, -1e-3)},
    },
    'low_texture': {'default': {'scene': 'low_texture'}},
    'repeated_texture': {'default': {'scene': 'repeated'}},
    'movers': {'default': {'movers': 2}, 'strong': {'movers': 4}},
}


@dataclass(frozen=True)
class CameraDraw:
    """One drawn camera: its effects and lens distortion (OpenCV order k1, k2, p1, p2)."""

    effects: Effects
    distortion: tuple[float, ...] = ()


def _distortion(rng: np.random.Generator) -> tuple[float, ...]:
    lo, hi = REALISM_RANGES['k1'][1]
    k1 = float(rng.uniform(lo, hi))
    k2 = float(rng.uniform(*REALISM_RANGES['k2'][1])) + (0.5 * k1 * k1 if k1 < 0 else 0.0)
    p1, p2 = (float(v) for v in rng.uniform(*REALISM_RANGES['p'][1], 2))
    return (k1, k2, p1, p2)


def draw_realism(seed: int, camera: Intrinsics | None = None) -> CameraDraw:
    """A random camera for a sequence, a pure function of ``seed`` (ranges: REALISM_RANGES).

    Args:
        seed: the sequence seed.
        camera: the pinhole camera the distortion must map one-to-one (default TUM fr3).
    """
    from initsel_ros.synth.render import Distorter

    rng = np.random.default_rng([int(seed), 0x7265616C])
    r = REALISM_RANGES

    def on(name: str) -> bool:
        return bool(rng.random() < r[name][0])

    def uniform(name: str) -> float:
        return float(rng.uniform(*r[name][1]))

    values: dict[str, Any] = {}
    values['exposure_time'] = uniform('exposure_time') if on('exposure_time') else 0.0
    values['line_delay'] = uniform('line_delay') if on('line_delay') else 0.0
    if on('gain_ramp_from'):
        ramp = [uniform('gain_ramp_from'), uniform('gain_ramp_to')]
        if rng.random() < 0.5:
            ramp.reverse()
        values['gain_ramp'] = (*ramp, uniform('gain_ramp_duration'), uniform('gain_ramp_start'))
    values['exposure'] = uniform('exposure') if on('exposure') else 0.0
    values['vignetting'] = uniform('vignetting')
    values['noise'] = uniform('noise')
    lo, hi = r['full_well'][1]
    values['full_well'] = (
        float(np.exp(rng.uniform(np.log(lo), np.log(hi)))) if on('full_well') else 0.0
    )
    values['jpeg_quality'] = (
        int(rng.integers(r['jpeg_quality'][1][0], r['jpeg_quality'][1][1] + 1))
        if on('jpeg_quality')
        else 0
    )
    values['blur'] = uniform('blur') if on('blur') else 0.0
    values['movers'] = (
        int(rng.integers(r['movers'][1][0], r['movers'][1][1] + 1)) if on('movers') else 0
    )
    distortion: tuple[float, ...] = ()
    if on('k1'):
        cam = camera or Intrinsics.tum_fr3()
        for _ in range(20):
            candidate = _distortion(rng)
            try:
                Distorter(dataclasses.replace(cam, distortion=candidate))
            except ConfigError:
                continue
            distortion = candidate
            break
    return CameraDraw(Effects(**values), distortion)


def effect_fields(
    effects: Sequence[str], level: str
) -> tuple[dict[str, Any], tuple[float, ...], str | None]:
    """The :class:`Effects` fields, distortion and scene of named effects at one strength.

    Args:
        effects: keys of EFFECT_LEVELS (a single-level effect uses its default).
        level: 'default' or 'strong'.

    Returns:
        ``(fields, distortion, scene)``; ``scene`` is None when no effect names one.
    """
    if level not in ('default', 'strong'):
        raise ConfigError(f"level must be 'default' or 'strong', got {level!r}")
    fields: dict[str, Any] = {}
    for name in effects:
        if name not in EFFECT_LEVELS:
            raise ConfigError(f'unknown effect {name!r}; known: {", ".join(EFFECT_LEVELS)}')
        levels = EFFECT_LEVELS[name]
        fields.update(levels.get(level, levels['default']))
    distortion = tuple(fields.pop('distortion', ()))
    scene = fields.pop('scene', None)
    return fields, distortion, None if scene is None else str(scene)


def effect_level(effect: str, level: str) -> tuple[Effects, tuple[float, ...], str]:
    """``(effects, distortion, scene)`` of a named effect strength.

    Args:
        effect: a key of EFFECT_LEVELS, or 'all' (every effect at ``level`` together, the
            scene variants excepted).
        level: 'clean', 'default' or 'strong' (a single-level effect uses its default).
    """
    if level == 'clean':
        return Effects(), (), 'structure_texture'
    if level not in ('default', 'strong'):
        raise ConfigError(f"level must be 'clean', 'default' or 'strong', got {level!r}")
    if effect == 'all':
        names = [n for n, lv in EFFECT_LEVELS.items() if 'scene' not in lv['default']]
    elif effect in EFFECT_LEVELS:
        names = [effect]
    else:
        raise ConfigError(f'unknown effect {effect!r}; known: {", ".join(EFFECT_LEVELS)}, all')
    fields, distortion, scene = effect_fields(names, level)
    return Effects(**fields), distortion, scene or 'structure_texture'


__all__ = [
    'EFFECT_LEVELS',
    'REALISM_RANGES',
    'CameraDraw',
    'draw_realism',
    'effect_fields',
    'effect_level',
]
