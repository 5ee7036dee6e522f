//! The debug messenger: every validation message is logged and counted, because a validation
//! run treats any message as a failure.

use std::ffi::{c_void, CStr};
use std::sync::Mutex;

use ash::vk;

/// Messages the validation layers reported. Shared with the driver through the messenger's
/// user-data pointer, so it lives in a `Box` owned by the context.
#[derive(Default)]
pub struct ValidationLog {
    messages: Mutex<Vec<String>>,
}

impl ValidationLog {
    pub fn count(&self) -> usize {
        self.messages.lock().map(|m| m.len()).unwrap_or(0)
    }

    pub fn messages(&self) -> Vec<String> {
        self.messages.lock().map(|m| m.clone()).unwrap_or_default()
    }

    fn push(&self, text: String) {
        if let Ok(mut m) = self.messages.lock() {
            m.push(text);
        }
    }
}

pub(super) fn messenger_info(log: &ValidationLog) -> vk::DebugUtilsMessengerCreateInfoEXT<'static> {
    vk::DebugUtilsMessengerCreateInfoEXT::default()
        .message_severity(vk::DebugUtilsMessageSeverityFlagsEXT::WARNING | vk::DebugUtilsMessageSeverityFlagsEXT::ERROR)
        .message_type(
            vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
        )
        .pfn_user_callback(Some(on_message))
        .user_data(log as *const ValidationLog as *mut c_void)
}

unsafe extern "system" fn on_message(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _kind: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user: *mut c_void,
) -> vk::Bool32 {
    // SAFETY: the layer passes a valid callback-data pointer, and `user` is the ValidationLog
    // that the context keeps alive (boxed) for as long as the messenger exists.
    let (text, log) = unsafe {
        let data = &*data;
        let text = if data.p_message.is_null() {
            String::from("(no message)")
        } else {
            CStr::from_ptr(data.p_message).to_string_lossy().into_owned()
        };
        (text, &*(user as *const ValidationLog))
    };
    if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR) {
        log::error!("validation: {text}");
    } else {
        log::warn!("validation: {text}");
    }
    log.push(text);
    vk::FALSE
}
