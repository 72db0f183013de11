#pragma once
// A dataset's classes.txt (`class_id class_name` per line, the name the rest of the line, '#'
// comments), read and written in one place: by the readers, the dataset writer and dqo_detect.

#include <map>
#include <string>

namespace dqo {

// Adds the file's classes to *class_names. A missing file adds none and is no error; a malformed
// line or a class listed twice is ("PATH:LINE: message").
bool read_class_list(const std::string& path, std::map<int, std::string>* class_names, std::string* error);

// The file's text for these classes (header line first), and the file written atomically.
std::string class_list_text(const std::map<int, std::string>& class_names);
bool write_class_list(const std::string& path, const std::map<int, std::string>& class_names, std::string* error);

}  // namespace dqo
