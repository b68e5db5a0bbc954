"""Coursework: exercises whose one function a student writes, and their checks.

Each exercise (:data:`EXERCISES`) is one equation of the seeds a course would set: the
thesis's FK and Jacobian, an RMRC step, the PD reference model, the environment
impedance, the compliance law, the disturbance observer, seed 004's planar IK, seed
002's null-space step and seed 003's leg IK. ``armlab exercise start NAME`` writes the
starter (:func:`write_starter`), ``armlab check FILE`` runs the cases
(:func:`check_file`: the student's file in a child process that only calls their
function, this process judging), a notebook calls :func:`check` on the function itself
(in its own kernel: formative, not a grade). The lab's
own implementation is each exercise's reference; the controller exercises also run the
student's law in closed loop on the simulated arm in place of the lab's.

:func:`load_student` loads a student's file and returns their function, or raises one
:class:`StudentError` with the student's file and line.
"""

from armlab.exercises.catalog import EXERCISES, get, starter_text
from armlab.exercises.checking import Report, Student, check, check_file, load_student
from armlab.exercises.notebook import notebook_json, write_starter
from armlab.exercises.student import StudentError

__all__ = ["EXERCISES", "Report", "Student", "StudentError", "check", "check_file", "get",
           "load_student", "notebook_json", "starter_text", "write_starter"]
