/* Symbol visibility for the slscan shared library: everything is hidden except the
 * functions marked SLS_API. */
#ifndef SLS_EXPORT_H
#define SLS_EXPORT_H

#if defined(SLS_STATIC)
#define SLS_API
#elif defined(_WIN32)
#if defined(SLS_BUILDING_LIBRARY)
#define SLS_API __declspec(dllexport)
#else
#define SLS_API __declspec(dllimport)
#endif
#else
#define SLS_API __attribute__((visibility("default")))
#endif

#endif /* SLS_EXPORT_H */
