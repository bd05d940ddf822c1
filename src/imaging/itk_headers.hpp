#pragma once
// ITK's headers, as read_volume.cpp uses them. Debian's ITK 5.2 ships a compiler-detection
// header generated for GCC alone: under clang it stops with "Unsupported compiler" (and clang's
// __GNUC__ 4.2 is below the 4.4 it asks of GCC). Clang implements every C++ feature that header
// probes, so it is included once here as if by GCC 4.9, clang's predefined macros restored right
// after; ITK's own includes of it then find its include guard set.
#if defined(__clang__) && !defined(ITK_COMPILER_DETECTION_H)
#pragma clang diagnostic push
#pragma clang diagnostic ignored "-Wbuiltin-macro-redefined"
#pragma push_macro("__clang__")
#pragma push_macro("__GNUC_MINOR__")
#undef __clang__
#undef __GNUC_MINOR__
#define __GNUC_MINOR__ 9
#include <itk_compiler_detection.h>
#pragma pop_macro("__GNUC_MINOR__")
#pragma pop_macro("__clang__")
#pragma clang diagnostic pop
#endif

#include <itkGDCMImageIO.h>
#include <itkGDCMSeriesFileNames.h>
#include <itkImage.h>
#include <itkImageSeriesReader.h>
#include <itkMetaImageIO.h>
#include <metaImage.h>
