"""Identification and validation: preprocessing, torque from current, estimation (OLS, bounded,
physically consistent), validation metrics, parameter files and URDF export.

Main entry points::

    prepare(recordings, spec, PreprocessConfig(), drive_gains=None) -> Prepared
    identify(spec, prepared, method="ols", model=ModelConfig(), weighting="none") -> IdentifiedModel
    identify_all(spec, prepared, ("ols", "bounded", "consistent"), ...) -> {method: IdentifiedModel}
    predict(identified, spec, q, qd, qdd) -> (N, 6) torques
    predict_recordings(params, recordings) -> Prediction (prepared data, predicted torques): the
        one prediction path of validate, gap --params, view and the live view (prediction.py)
    validate(identified, spec, prepared) -> ValidationResult
    save_params(identified, path) / load_params(path)
    resolve_preset(spec, prepared, "auto") -> PresetChoice (model, weighting, what CV chose)
"""

from urident.ident.design import ModelConfig, design_matrix
from urident.ident.estimate import Estimate
from urident.ident.identify import (METHODS, IdentifiedModel, identify, identify_all, predict,
                                    predict_prepared, prepare)
from urident.ident.params_file import ParamsFileError, load_params, save_params
from urident.ident.presets import PRESETS, PresetChoice, resolve_preset
from urident.ident.preprocess import (PreprocessConfig, Prepared, accelerations, concatenate,
                                      preprocess, zero_phase_lowpass)
from urident.ident.torque import estimate_drive_gains, torque_from_current
from urident.ident.metrics import RunningMetrics, error_metrics, metrics
from urident.ident.prediction import (Prediction, StreamPredictor, load_prediction_params,
                                      nominal_parameters, parameters_from_vector, predict_recordings,
                                      prediction_config)
from urident.ident.validate import ValidationResult, validate

__all__ = [
    "METHODS", "PRESETS", "Estimate", "PresetChoice", "resolve_preset", "IdentifiedModel", "ModelConfig", "ParamsFileError", "PreprocessConfig",
    "Prediction", "Prepared", "RunningMetrics", "StreamPredictor", "ValidationResult", "accelerations", "concatenate", "design_matrix",
    "error_metrics", "estimate_drive_gains", "identify", "identify_all", "load_params", "load_prediction_params", "metrics", "nominal_parameters",
    "parameters_from_vector",
    "predict", "predict_prepared", "predict_recordings", "prediction_config", "prepare", "preprocess", "save_params", "torque_from_current",
    "validate", "zero_phase_lowpass",
]
