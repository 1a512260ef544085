// dtis: the public C++ API in one header (docs/library.md).
//
//   dtis::io::LoadJob / RunJob             a job file planned and verified in-process
//   dtis::kinematics::LoadMachineFile      a machine from its file
//   dtis::PathSource, dtis::Machine        the two contracts, to plan your own paths and machines
//   dtis::interp::PlanVpop                 the interpolator, setpoints into any SetpointSink
//   dtis::interp::Verify                   the independent verifier
//   dtis::io::ReadSetpoints / WriteRunOutputs   setpoint files
#pragma once

#include "dtis/core/error.hpp"
#include "dtis/core/machine.hpp"
#include "dtis/core/path_source.hpp"
#include "dtis/core/pose.hpp"
#include "dtis/core/version.hpp"
#include "dtis/geometry/step_model.hpp"
#include "dtis/interp/program.hpp"
#include "dtis/interp/verifier.hpp"
#include "dtis/interp/vpop.hpp"
#include "dtis/io/job.hpp"
#include "dtis/io/setpoint_file.hpp"
#include "dtis/io/stream.hpp"
#include "dtis/kinematics/machines.hpp"
